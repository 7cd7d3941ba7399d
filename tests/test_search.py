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
    return check_path(clips, frames, audio, own, None, FPS, 0.1)


CFG = SearchParams(tolerance=0.1, beam_size=64, n_start=40, n_save=100, max_paths_per_start=50,
                   max_expansions=400000, temperature=0.05)


@pytest.mark.parametrize("seed", range(6))
def test_beam_and_dfs_satisfy_constraints_and_beam_is_no_worse(seed):
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
    cons = build_constraints(own, None, T, FPS, CFG)
    rb = beam_search(g, cons, CFG, seed=seed)
    rd = stochastic_greedy_search(g, cons, CFG, seed=seed)
    assert rb.success, rb.failed_segment
    rep = _check(g, audio, rb, own, CFG)
    assert rep["met"] == rep["total"], rep
    assert len(rb.path) == T
    if rd.success:
        rep = _check(g, audio, rd, own, CFG)
        assert rep["met"] == rep["total"]
        # deterministic mode (no sampling noise, wide beam): never worse than the depth-first search
        greedy = dataclasses.replace(CFG, temperature=1e-9, beam_size=1024)
        rg = beam_search(g, cons, greedy, seed=seed)
        assert rg.success and rg.cost <= rd.cost + 1e-5


def test_impossible_constraint_is_reported_not_raised():
    rng = np.random.default_rng(0)
    g, audio = small_graph(rng)
    own = seg([("LR", 1.0, 1.2, 1.5)])  # no state is a listener response
    cons = build_constraints(own, None, 30, FPS, CFG)
    for fn in (beam_search, stochastic_greedy_search):
        r = fn(g, cons, CFG, seed=0)
        assert not r.success and r.path is None
        assert r.failed_segment["kind"] == "LR"
    cfg_none = dataclasses.replace(CFG, use_constraints=False)
    assert beam_search(g, build_constraints(own, None, 30, FPS, cfg_none), cfg_none).success


def test_ablation_switches_change_the_constraints():
    own = seg([("PC", 0.5, 0.8, 1.5), ("LR", 2.0, 2.1, 2.4)])
    par = seg([("HP", 3.0, 3.1, 3.6)])
    full = build_constraints(own, par, 50, FPS, CFG)
    assert {s["kind"] for s in full.segments} == {"PC", "LR", "PH", "idle"}
    no_lr = build_constraints(own, par, 50, FPS, SearchParams(use_lr=False))
    assert "LR" not in {s["kind"] for s in no_lr.segments} and (no_lr.own_req[20:24] == -1).all()
    no_hp = build_constraints(own, par, 50, FPS, SearchParams(use_hp=False))
    assert "PH" not in {s["kind"] for s in no_hp.segments} and (no_hp.partner_req == -1).all()
    none = build_constraints(own, par, 50, FPS, SearchParams(use_constraints=False))
    assert none.total == 0 and (none.own_req == -1).all()
    # PC core: [s + tol, e - tol); peak window [p - tol, p + tol]
    assert (full.own_req[6:14] == 1).all() and full.own_req[5] == -1 and full.peak_reset[7] and full.peak_check[9]


def test_blinks_follow_the_rules():
    rng = np.random.default_rng(0)
    t = blink_times([0.5, 0.9, 2.0, 2.5, 3.6, 12.0], 15.0, rng)
    assert t[0] == 0.5 and 0.9 not in t and 2.0 in t and 2.5 not in t and 3.6 in t and 12.0 in t
    assert np.all(np.diff(np.concatenate([[0], t, [15.0]])) <= 5.0 + 1e-9)  # never 5 s without a blink
    c = blink_curve([1.0], 60, 30.0)
    assert c.max() == pytest.approx(1.0, abs=0.2) and c[29] == 0 and c[30] == 0 and c[31] > 0
    assert np.count_nonzero(c) == pytest.approx(0.17 * 30, abs=1)
