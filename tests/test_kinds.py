"""The registry of constraint kinds (annotate/kinds.py): its built-in table is the one the search,
checker and co-occurrence code always used, and a made-up kind added through the registry alone
(plus an annotation that produces its segments) is constrained by the search and verified by the
checker, with no other code changed."""
import numpy as np
import pandas as pd
import pytest

from convsynth_jax.annotate import kinds
from convsynth_jax.annotate.kinds import ConstraintKind, register_kind, unregister_kind
from convsynth_jax.annotate.types import FrameAudio
from convsynth_jax.errors import ConfigError
from convsynth_jax.graph.types import MotionGraph
from convsynth_jax.search.beam import beam_search
from convsynth_jax.search.check import check_path
from convsynth_jax.search.constraints import build_constraints
from convsynth_jax.search.dfs import stochastic_greedy_search
from convsynth_jax.search.params import SearchParams
from convsynth_jax.search.relax import constraint_order

FPS = 10.0
T = 60


def test_builtin_table():
    """The built-in kinds and hypotheses, spelled out once more here as the specification."""
    got = [(k.name, k.label, k.code, k.channel, k.has_peak, k.retimable, k.weight, k.switch)
           for k in kinds.constraint_kinds()]
    assert got == [("PC", "PC", 1, "own", True, True, "weight_pc", None),
                   ("LR", "LR", 2, "own", False, True, "weight_lr", "use_lr"),
                   ("PH", "HP", 3, "partner", False, False, "weight_hp", "use_hp"),
                   ("idle", "idle", 0, "own", False, False, "weight_idle", None)]
    assert [(h.name, h.channel, h.label, h.motions, h.planting) for h in kinds.hypotheses()] == [
        ("PC-LH", "own", "PC", ("LH",), "p_pc_lh"), ("PC-RH", "own", "PC", ("RH",), "p_pc_rh"),
        ("PC-LH/RH", "own", "PC", ("LH", "RH"), "p_pc_either"), ("LR-Nod", "own", "LR", ("Nod",), "p_lr_nod"),
        ("PH-Nod", "partner", "HP", ("Nod",), "p_ph_nod")]
    p = SearchParams(weight_pc=7.0, use_lr=False)
    assert kinds.constraint_kind("PC").weight_of(p) == 7.0 and not kinds.constraint_kind("LR").enabled(p)
    assert kinds.kind_of_segment("own", "HP") is None and kinds.kind_of_segment("partner", "HP").name == "PH"


def test_registration_errors_name_the_kind():
    with pytest.raises(ConfigError, match="'PC' is registered already"):
        register_kind(ConstraintKind("PC", "PC"))
    with pytest.raises(ConfigError, match="'X': channel"):
        register_kind(ConstraintKind("X", "X", channel="both"))
    with pytest.raises(ConfigError, match="'X': partner kinds can have no peak"):
        register_kind(ConstraintKind("X", "X", channel="partner", has_peak=True))
    with pytest.raises(ConfigError, match="unknown constraint kind 'X'"):
        kinds.constraint_kind("X")
    with pytest.raises(ConfigError, match="'X': its weight names search.weight_x"):
        ConstraintKind("X", "X", weight="weight_x").weight_of(SearchParams())


# ------------------------------------------------------------------------------------ a made-up kind
def laughter_segments(envelope: np.ndarray, fps: float, threshold: float = 0.5) -> pd.DataFrame:
    """The made-up kind's annotation: laughter (LG) wherever a per-frame laughter envelope exceeds
    ``threshold``; DataFrame[kind, start, peak, end] (seconds, no F0 peak)."""
    on = np.concatenate([[0], (envelope > threshold).astype(np.int8), [0]])
    d = np.flatnonzero(np.diff(on))
    return pd.DataFrame([("LG", a / fps, np.nan, b / fps) for a, b in zip(d[::2], d[1::2])],
                        columns=["kind", "start", "peak", "end"])


@pytest.fixture
def laughter():
    kind = register_kind(ConstraintKind("LG", "LG", channel="own", weight=3.0))
    yield kind
    unregister_kind("LG")
    assert "LG" not in kinds.AUDIO_LABELS


def _clip(rng, frames):
    """One database clip's annotation: own clauses (PC, with an F0 peak), listener responses and
    laughter (from a laughter envelope, through ``laughter_segments``), partner hesitations."""
    rows, env = [], np.zeros(frames)
    f, i = int(rng.integers(2, 6)), int(rng.integers(0, 4))
    while f < frames - 8:
        n = int(rng.integers(5, 10))
        kind, i = ["LG", "PC", "LG", "LR"][i % 4], i + 1
        if kind == "LG":
            env[f:f + n] = rng.uniform(0.6, 1.0, n)
        else:
            rows.append((kind, f / FPS, (f + n // 2) / FPS if kind == "PC" else np.nan, (f + n) / FPS))
        f += n + int(rng.integers(3, 7))
    own = pd.concat([pd.DataFrame(rows, columns=["kind", "start", "peak", "end"]), laughter_segments(env, FPS)],
                    ignore_index=True).sort_values("start", ignore_index=True)
    a = int(rng.integers(0, frames - 6))
    par = pd.DataFrame([("HP", a / FPS, np.nan, (a + 3) / FPS)], columns=["kind", "start", "peak", "end"])
    return own, par


def _graph(rng, n_clips=4, frames=80):
    """A motion graph over the clips: original chains plus random synthetic edges; the per-state
    audio labels come from the clips' segments (FrameAudio.from_segments reads the registry)."""
    segs, audio, arrs = {}, {}, []
    for c in range(n_clips):
        own, par = _clip(rng, frames)
        segs[f"c{c}"] = (own, par)
        fo, fp = FrameAudio.from_segments(own, frames, FPS), FrameAudio.from_segments(par, frames, FPS)
        audio[f"c{c}"] = (fo, fp)
        arrs.append((np.full(frames, c), np.arange(frames), fo.label, fo.seg_start, fo.seg_end, fo.seg_peak,
                     fp.label, fp.seg_start, fp.seg_end))
    S = n_clips * frames
    edges = []
    for s in range(S):
        if (s + 1) % frames:
            edges.append((s, s + 1, 0.0, False))
        for t in rng.choice(S, 3, replace=False):
            if t != s + 1:
                edges.append((s, int(t), float(rng.uniform(1, 5)), True))
    edges.sort(key=lambda x: x[0])
    rows, cols, cost, syn = (np.asarray(x) for x in zip(*edges))
    indptr = np.concatenate([[0], np.cumsum(np.bincount(rows, minlength=S))])
    cols_ = [np.concatenate([a[i] for a in arrs]).astype(np.int32) for i in range(9)]
    g = MotionGraph(tuple(audio), FPS, *cols_, np.ones(S, bool), indptr, cols.astype(np.int32),
                    cost.astype(np.float32), syn.astype(bool), {})
    return g, audio, segs


def _input(segs, T):
    """The window's input: clip c0's own and partner segments over its first T frames."""
    own, par = segs["c0"]
    return own[own.end <= T / FPS].reset_index(drop=True), par[par.end <= T / FPS].reset_index(drop=True)


@pytest.mark.parametrize("matching,method", [("paper", "beam"), ("labels", "beam"), ("paper", "dfs")])
def test_made_up_kind_is_searched_and_checked(laughter, matching, method):
    rng = np.random.default_rng(3)
    g, audio, segs = _graph(rng)
    assert (g.own_label == laughter.code).any()        # the graph's states carry the new label
    own, par = _input(segs, T)
    assert (own.kind == "LG").sum() >= 2
    p = SearchParams(matching=matching, tolerance=0.1, beam_size=64, max_degree=16, n_start=20, n_save=50)
    cons = build_constraints(own, par, T, FPS, p)
    lg = [s for s in cons.segments if s["kind"] == "LG"]
    assert len(lg) == (own.kind == "LG").sum() and all(s["channel"] == "own" for s in lg)
    search = beam_search if method == "beam" else stochastic_greedy_search
    res = search(g, cons, p, seed=0)
    assert res.success, res.failure
    path = np.asarray(res.path)
    chk = check_path([g.clip_names[g.clip[y]] for y in path], g.frame[path], audio, own, par, FPS, 0.1,
                     matching=matching)
    assert chk["met"] == chk["total"] == cons.total
    assert sum(d["kind"] == "LG" and d["met"] for d in chk["details"]) == len(lg)
    # the search really is held to the new kind: playing the clip 6 frames late misses its laughter
    late = np.clip(np.arange(T) - 6, 0, None)
    chk_late = check_path(["c0"] * T, late, audio, own, par, FPS, 0.1, matching=matching)
    assert any(d["kind"] == "LG" and not d["met"] for d in chk_late["details"])
    # without the kind registered, the same input constrains no laughter (the segments are free)
    unregister_kind("LG")
    try:
        assert not any(s["kind"] == "LG" for s in build_constraints(own, par, T, FPS, p).segments)
    finally:
        register_kind(laughter)


def test_a_switched_kind_names_its_condition_in_failures():
    from convsynth_jax.search.result import next_step

    register_kind(ConstraintKind("Q", "Q", channel="partner", switch="use_questions", description="questions"))
    try:
        assert "leaving the questions out (condition no_questions)" in next_step(SearchParams(), {"kind": "Q"})
        assert kinds.constraint_kind("Q").enabled(SearchParams())     # a switch SearchParams lacks is on
    finally:
        unregister_kind("Q")


def test_made_up_kind_weight_orders_best_effort(laughter):
    keys = [("idle", 0, 3), ("LR", 5, 9), ("LG", 12, 20), ("PC", 30, 40), ("PH", 1, 4)]
    order = constraint_order(keys, SearchParams())
    assert [k[0] for k in order] == ["PC", "LG", "PH", "LR", "idle"]    # 4, 3 (the kind's own), 2, 2, 1


def test_the_viewer_shows_a_registered_kinds_labels():
    """The viewer's timeline reads the registry: a made-up own kind's segments are kept, and a partner
    kind's checker details go to the partner (as PH does to HP)."""
    from convsynth_jax.viewer.scene import _labels_from_report, label_kinds

    register_kind(ConstraintKind("LG", "LG", channel="own", weight=3.0))
    register_kind(ConstraintKind("PQ", "Q", channel="partner", weight=1.0))
    try:
        assert label_kinds()[:3] == ("PC", "LR", "HP") and {"LG", "Q"} <= set(label_kinds())
        rep = {"segments": {"a": [{"kind": "LG", "start": 1.0, "end": 2.0}, {"kind": "ZZ", "start": 0, "end": 1}]}}
        assert _labels_from_report(rep, ["a", "b"], {"a": 30.0, "b": 30.0})["a"] == [{"kind": "LG", "start": 1.0, "end": 2.0}]
        det = {"characters": {"a": {"checker": {"details": [{"kind": "PQ", "start": 30, "end": 60},
                                                            {"kind": "PH", "start": 90, "end": 120}]}}}}
        got = _labels_from_report(det, ["a", "b"], {"a": 30.0, "b": 30.0})
        assert got["a"] == [] and got["b"] == [{"kind": "HP", "start": 3.0, "end": 4.0}, {"kind": "Q", "start": 1.0, "end": 2.0}]
    finally:
        unregister_kind("LG")
        unregister_kind("PQ")
    assert label_kinds() == ("PC", "LR", "HP")
