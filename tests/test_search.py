import dataclasses
import numpy as np
import pandas as pd
import pytest

from convsynth_jax.annotate.types import FrameAudio
from convsynth_jax.graph.types import MotionGraph
from convsynth_jax.search.beam import beam_search
from convsynth_jax.search.check import check_path
from convsynth_jax.search.constraints import build_constraints
from convsynth_jax.search.dfs import stochastic_greedy_search
from convsynth_jax.search.params import SearchParams
from convsynth_jax.synth.blinks import blink_curve, blink_times

FPS = 10.0


def seg(rows):
    return pd.DataFrame(rows, columns=["kind", "start", "peak", "end"])


def small_graph(rng, n_clips=4, frames=60, extra_edges=3):
    """Clips with one PC each at varying places, original chains plus random synthetic edges."""
    labels, starts, ends, peaks, clip, frame = [], [], [], [], [], []
    for c in range(n_clips):
        s = int(rng.integers(5, 25)); e = s + int(rng.integers(8, 20)); p = s + int(rng.integers(1, e - s - 1))
        lab = np.zeros(frames, np.int8); lab[s:e] = 1
        labels.append(lab); starts.append(np.where(lab > 0, s, -1)); ends.append(np.where(lab > 0, e, -1))
        peaks.append(np.where(lab > 0, p, -1)); clip.append(np.full(frames, c)); frame.append(np.arange(frames))
    cat = lambda x: np.concatenate(x).astype(np.int32)  # noqa: E731
    S = n_clips * frames
    rows, cols, cost, syn = [], [], [], []
    for c in range(n_clips):
        for f in range(frames - 1):
            rows.append(c * frames + f); cols.append(c * frames + f + 1); cost.append(0.0); syn.append(False)
    for s in range(S):
        for t in rng.choice(S, extra_edges, replace=False):
            if t != s + 1:
                rows.append(s); cols.append(int(t)); cost.append(float(rng.uniform(1, 10))); syn.append(True)
    # wrap each clip's end back to its start so paths can be long
    for c in range(n_clips):
        rows.append(c * frames + frames - 1); cols.append(c * frames); cost.append(5.0); syn.append(True)
    rows, cols, cost, syn = map(np.asarray, (rows, cols, cost, syn))
    o = np.lexsort((cols, rows))
    rows, cols, cost, syn = rows[o], cols[o], cost[o], syn[o]
    indptr = np.concatenate([[0], np.cumsum(np.bincount(rows, minlength=S))])
    z = np.zeros(S, np.int32)
    g = MotionGraph(tuple(f"c{c}" for c in range(n_clips)), FPS, cat(clip), cat(frame), cat(labels), cat(starts),
                    cat(ends), cat(peaks), z, z - 1, z - 1, np.ones(S, bool), indptr, cols, cost.astype(np.float32),
                    syn, {})
    audio = {f"c{c}": (FrameAudio(labels[c], starts[c].astype(np.int32), ends[c].astype(np.int32), peaks[c].astype(np.int32)),
                       FrameAudio(np.zeros(frames, np.int8), *(np.full(frames, -1, np.int32),) * 3)) for c in range(n_clips)}
    return g, audio


def _check(g, audio, res, own, cfg):
    clips = [g.clip_names[g.clip[s]] for s in res.path]
    frames = [int(g.frame[s]) for s in res.path]
    return check_path(clips, frames, audio, own, None, FPS, 0.1, matching=cfg.matching)


CFG = SearchParams(tolerance=0.1, beam_size=64, n_start=40, n_save=100, max_paths_per_start=50,
                   max_expansions=400000, temperature=0.05)


@pytest.mark.parametrize("matching", ["paper", "labels"])
@pytest.mark.parametrize("seed", range(6))
def test_beam_and_dfs_satisfy_constraints_and_beam_is_no_worse(seed, matching):
    # paper matching must land on one whole source clause: a beam as wide as the graph (240 states)
    cfg = dataclasses.replace(CFG, matching=matching, beam_size=256 if matching == "paper" else CFG.beam_size)
    rng = np.random.default_rng(seed)
    g, audio = small_graph(rng)
    # the input: one clause copied from a database clip, shifted in time
    c = int(rng.integers(4))
    s, e, p = (int(audio[f"c{c}"][0].seg_start[audio[f"c{c}"][0].label > 0][0]),
               int(audio[f"c{c}"][0].seg_end[audio[f"c{c}"][0].label > 0][0]),
               int(audio[f"c{c}"][0].seg_peak[audio[f"c{c}"][0].label > 0][0]))
    shift = int(rng.integers(3, 10))
    T = 45
    own = seg([("PC", (s - s + shift) / FPS, (p - s + shift) / FPS, (e - s + shift) / FPS)])
    cons = build_constraints(own, None, T, FPS, cfg)
    rb = beam_search(g, cons, cfg, seed=seed)
    rd = stochastic_greedy_search(g, cons, cfg, seed=seed)
    assert rb.success, rb.failed_segment
    rep = _check(g, audio, rb, own, cfg)
    assert rep["met"] == rep["total"], rep
    assert len(rb.path) == T
    if rd.success:
        rep = _check(g, audio, rd, own, cfg)
        assert rep["met"] == rep["total"]
        # deterministic mode (no sampling noise, wide beam): never worse than the depth-first search
        greedy = dataclasses.replace(cfg, temperature=1e-9, beam_size=1024)
        rg = beam_search(g, cons, greedy, seed=seed)
        assert rg.success and rg.cost <= rd.cost + 1e-5


@pytest.mark.parametrize("matching", ["paper", "labels"])
def test_impossible_constraint_is_reported_not_raised(matching):
    rng = np.random.default_rng(0)
    g, audio = small_graph(rng)
    cfg = dataclasses.replace(CFG, matching=matching)
    own = seg([("LR", 1.0, 1.2, 1.5)])  # no state is a listener response
    cons = build_constraints(own, None, 30, FPS, cfg)
    for fn in (beam_search, stochastic_greedy_search):
        r = fn(g, cons, cfg, seed=0)
        assert not r.success and r.path is None
        assert r.failed_segment["kind"] == "LR"
        assert "LR constraint" in r.failure and matching in r.failure
    cfg_none = dataclasses.replace(CFG, use_constraints=False)
    assert beam_search(g, build_constraints(own, None, 30, FPS, cfg_none), cfg_none).success


@pytest.mark.parametrize("matching", ["paper", "labels"])
def test_ablation_switches_change_the_constraints(matching):
    own = seg([("PC", 0.5, 0.8, 1.5), ("LR", 2.0, 2.1, 2.4)])
    par = seg([("HP", 3.0, 3.1, 3.6)])
    full = build_constraints(own, par, 50, FPS, dataclasses.replace(CFG, matching=matching))
    assert {s["kind"] for s in full.segments} == {"PC", "LR", "PH", "idle"}
    no_lr = build_constraints(own, par, 50, FPS, SearchParams(use_lr=False, matching=matching))
    assert "LR" not in {s["kind"] for s in no_lr.segments} and (no_lr.own_req[20:24] == -1).all()
    no_hp = build_constraints(own, par, 50, FPS, SearchParams(use_hp=False, matching=matching))
    assert "PH" not in {s["kind"] for s in no_hp.segments} and (no_hp.partner_req == -1).all()
    none = build_constraints(own, par, 50, FPS, SearchParams(use_constraints=False, matching=matching))
    assert none.total == 0 and (none.own_req == -1).all()
    # PC core: [s + tol, e - tol)
    assert (full.own_req[6:14] == 1).all() and full.own_req[5] == -1
    if matching == "labels":  # peak window [p - tol, p + tol]
        assert full.peak_reset[7] and full.peak_check[9]
    else:  # entry windows [s - tol, s + tol] of PC (4..6), LR (19..21) and partner HP (29..31)
        pa = full.paper
        assert (pa.own_kind[4:7] == 1).all() and pa.own_kind[3] == -1 and pa.own_kind[7] == -1
        assert (pa.own_kind[19:22] == 2).all() and pa.own_reset[19] and pa.own_check[21]
        assert (pa.par_kind[29:32] == 3).all() and pa.par_check[31] and pa.own_peak[5] == 8
        assert (pa.own_free[19:22] == False).all() and no_lr.paper.own_free[20]  # noqa: E712


def test_short_segments_are_constraints_only_in_paper_mode():
    own = seg([("PC", 1.0, 1.1, 1.2), ("LR", 2.0, np.nan, 2.1)])  # 0.2 s and 0.1 s
    kinds = {m: [s["kind"] for s in build_constraints(own, None, 40, FPS, dataclasses.replace(CFG, matching=m))
                 .segments] for m in ("paper", "labels")}
    assert kinds["paper"].count("PC") == 1 and kinds["paper"].count("LR") == 1
    assert "PC" not in kinds["labels"] and "LR" not in kinds["labels"]


def test_unknown_matching_mode_is_a_config_error():
    from convsynth_jax.errors import ConfigError

    with pytest.raises(ConfigError, match="search.matching"):
        build_constraints(seg([]), None, 10, FPS, SearchParams(matching="exact"))


def test_paper_checker_rejects_a_clause_stitched_from_two_source_clauses():
    """A path whose associated audio has the right run of PC labels (labels mode: met) but plays the
    first half of one source clause and the second half of another (paper: not met); and the same
    input matched by one whole source clause, which both modes accept."""
    n = 40
    lab_a, lab_b = np.zeros(n, np.int8), np.zeros(n, np.int8)
    lab_a[10:20], lab_b[10:20] = 1, 1
    st, en, pk = np.where(lab_a > 0, 10, -1), np.where(lab_a > 0, 20, -1), np.where(lab_a > 0, 15, -1)
    fa = lambda lab: FrameAudio(lab, *(x.astype(np.int32) for x in (st, en, pk)))  # noqa: E731
    idle = FrameAudio(np.zeros(n, np.int8), *(np.full(n, -1, np.int32),) * 3)
    audio = {"a": (fa(lab_a), idle), "b": (fa(lab_b), idle)}
    own = seg([("PC", 1.0, 1.5, 2.0)])
    whole = (["a"] * 30, list(range(30)))
    stitched = (["a"] * 15 + ["b"] * 15, list(range(15)) + list(range(15, 30)))
    late = (["a"] * 30, list(range(8)) + list(range(10, 30)) + [30, 31])  # starts 2 frames late, ends 2 late
    for clips, frames in (whole, stitched, late):
        assert len(clips) == len(frames) == 30
    verdict = {}
    for name, (clips, frames) in {"whole": whole, "stitched": stitched}.items():
        for m in ("paper", "labels"):
            rep = check_path(clips, frames, audio, own, None, FPS, 0.1, matching=m)
            pc = [d for d in rep["details"] if d["kind"] == "PC"]
            verdict[name, m] = pc[0]["met"]
    assert verdict == {("whole", "paper"): True, ("whole", "labels"): True,
                       ("stitched", "paper"): False, ("stitched", "labels"): True}


def test_blinks_follow_the_rules():
    rng = np.random.default_rng(0)
    t = blink_times([0.5, 0.9, 2.0, 2.5, 3.6, 12.0], 15.0, rng)
    assert t[0] == 0.5 and 0.9 not in t and 2.0 in t and 2.5 not in t and 3.6 in t and 12.0 in t
    assert np.all(np.diff(np.concatenate([[0], t, [15.0]])) <= 5.0 + 1e-9)  # never 5 s without a blink
    c = blink_curve([1.0], 60, 30.0)
    assert c.max() == pytest.approx(1.0, abs=0.2) and c[29] == 0 and c[30] == 0 and c[31] > 0
    assert np.count_nonzero(c) == pytest.approx(0.17 * 30, abs=1)


def test_paper_placement_rule_matches_a_plain_comparison_everywhere():
    """The vectorized placement test (kernel and DFS) against the rule written out: start, end and
    peak of the source segment each within the tolerance of the input's, on an exhaustive grid
    (the kernel-vs-reference tests alone did not notice an entry allowed 3 frames late)."""
    import itertools

    from convsynth_jax.search.constraints import NO_PEAK, placement_ok

    tol, t, s, e = 3, 40, 35, 50
    for kind, peak in ((1, 42), (2, NO_PEAK)):
        labels, offsets, lengths, peaks = (np.array(v) for v in zip(*itertools.product(
            (1, 2), range(0, 12), range(8, 24), (-1, 0, 3, 6, 9, 12))))
        got = placement_ok(labels, offsets, lengths, peaks, t, (kind, s, e, peak), tol)
        for i in range(labels.size):
            st = t - offsets[i]
            want = (labels[i] == kind and abs(st - s) <= tol and abs(st + lengths[i] - e) <= tol
                    and (peak == NO_PEAK or (peaks[i] >= 0 and abs(st + peaks[i] - peak) <= tol)))
            assert bool(got[i]) == want, (labels[i], offsets[i], lengths[i], peaks[i])


def test_placement_rule_with_a_start_slack_matches_the_rule_written_out():
    """With a start tolerance stol > tol (search.start_slack_factor) the start may lie up to stol off;
    the instance is then read as moved back by its offset beyond tol, and its end and peak must lie
    within their tolerances of the input's after that move. With stol == tol the rule is the plain one
    (an exhaustive grid)."""
    import itertools

    from convsynth_jax.search.constraints import placement_ok

    tol, t, s, e, p, etol, ptol = 2, 40, 35, 50, 42, 4, 3
    labels, offsets, lengths, peaks = (np.array(v) for v in zip(*itertools.product(
        (1,), range(0, 16), range(8, 24), (-1, 0, 3, 6, 9, 12))))
    for stol in (tol, tol + 5):
        got = placement_ok(labels, offsets, lengths, peaks, t, (1, s, e, p, etol, ptol, stol), tol)
        for i in range(labels.size):
            st = t - offsets[i]
            x = st - s
            shift = 0 if abs(x) <= tol else (x - tol if x > 0 else x + tol)
            want = (abs(x) <= stol and abs(st - shift + lengths[i] - e) <= etol
                    and peaks[i] >= 0 and abs(st - shift + peaks[i] - p) <= ptol)
            if stol == tol:   # no shift within tol: the rule without slack
                assert shift == 0 or not want
            assert bool(got[i]) == want, (stol, offsets[i], lengths[i], peaks[i])
        if stol > tol:   # an instance 7 frames early with the input's duration and peak offset is admitted
            assert placement_ok(1, 0, e - s, p - s, s - 7, (1, s, e, p, etol, ptol, stol), tol)
            assert not placement_ok(1, 0, e - s, p - s, s - 7, (1, s, e, p, etol, ptol, tol), tol)


@pytest.mark.parametrize("method", ["beam", "dfs"])
def test_labels_search_keeps_touching_clauses_apart_as_the_checker_does(method):
    """An input clause split at a word boundary into two touching PCs [s, m) and [m, e). In
    ``labels`` matching both share their margins, so the source clause [s, e) played straight through
    met the search's per-frame masks while the checker (a run of PC starting and ending within the
    tolerance of each clause) rejected both clauses: the recorded sweep's 4 disagreements. Now every
    path the search returns meets every constraint by the checker, and some seeds find one."""
    solved = 0
    for seed in range(4):
        g, audio = small_graph(np.random.default_rng(seed), extra_edges=8)
        lab = audio["c0"][0].label
        s, e = (int(x) for x in np.flatnonzero(np.diff(np.concatenate([[0], lab, [0]]))))
        m = (s + e) // 2
        own = seg([("PC", s / FPS, np.nan, m / FPS), ("PC", m / FPS, np.nan, e / FPS)])
        cfg = dataclasses.replace(CFG, matching="labels", method=method)
        cons = build_constraints(own, None, 60, FPS, cfg)
        search = beam_search if method == "beam" else stochastic_greedy_search
        res = search(g, cons, cfg, seed=seed)
        if res.success:
            chk = _check(g, audio, res, own, cfg)
            assert chk["met"] == chk["total"] == res.constraints_total, (seed, chk["details"])
            solved += 1
    assert solved >= 1
