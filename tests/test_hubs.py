"""Transition targets that represent the recordings: the hub term on synthetic edges (graph/hubs.py,
``synth.hub_penalty``)."""
import dataclasses

import numpy as np
import pytest

from convsynth_jax.graph.hubs import hub_costs, synthetic_in_degree
from convsynth_jax.search.beam import beam_search
from convsynth_jax.search.constraints import build_constraints
from convsynth_jax.search.params import SearchParams
from convsynth_jax.systems.motion_graph import penalized_graph
from tests.test_search import FPS, small_graph


def with_hub(g, hub: int, cost: float):
    """``g`` plus a synthetic edge from every state (without one already) into ``hub`` at ``cost``: a
    state near the mean pose that every other state is close to."""
    src = np.repeat(np.arange(g.num_states), np.diff(g.indptr))
    have = set(src[g.indices == hub].tolist())
    add = np.array([s for s in range(g.num_states) if s not in have and s != hub - 1 and s != hub])
    rows = np.concatenate([src, add])
    cols = np.concatenate([g.indices, np.full(add.size, hub)])
    cost_ = np.concatenate([g.cost, np.full(add.size, cost, np.float32)])
    syn = np.concatenate([g.synthetic, np.ones(add.size, bool)])
    o = np.lexsort((cols, rows))
    indptr = np.concatenate([[0], np.cumsum(np.bincount(rows, minlength=g.num_states))])
    return dataclasses.replace(g, indptr=indptr, indices=cols[o], cost=cost_[o].astype(np.float32), synthetic=syn[o])


def reference_hub_costs(g, weight, cap, ends="target"):
    """Edge by edge: count each state's synthetic in- and out-edges, then price every synthetic edge."""
    deg_in, deg_out = [0] * g.num_states, [0] * g.num_states
    for s in range(g.num_states):
        for e in range(int(g.indptr[s]), int(g.indptr[s + 1])):
            if g.synthetic[e]:
                deg_in[int(g.indices[e])] += 1
                deg_out[s] += 1
    mean = sum(deg_in) / g.num_states
    m = float(np.median([float(c) for c, s in zip(g.cost, g.synthetic) if s]))
    out = []
    for s in range(g.num_states):
        for e in range(int(g.indptr[s]), int(g.indptr[s + 1])):
            rel = min(deg_in[int(g.indices[e])] / mean, cap)
            if ends == "both":
                rel = 0.5 * (rel + min(deg_out[s] / mean, cap))
            out.append(weight * m * rel if g.synthetic[e] else 0.0)
    return np.array(out)


def test_hub_costs_match_the_edge_by_edge_reference():
    g, _ = small_graph(np.random.default_rng(0))
    g = with_hub(g, 7, 0.5)
    deg = synthetic_in_degree(g)
    assert deg[7] > 20 * np.mean(deg)
    for weight, cap in ((1.0, 4.0), (2.5, 100.0), (0.0, 4.0), (5.0, 16.0)):
        for ends in ("target", "both"):
            assert np.allclose(hub_costs(g, weight, cap, ends), reference_hub_costs(g, weight, cap, ends))
    assert not hub_costs(g, 1.0, 4.0)[~g.synthetic].any()


def test_hub_penalty_keeps_paths_from_converging_on_a_hub():
    """Every state has a synthetic edge into one hub, cheaper than all its others: unconstrained paths
    keep returning to it; with synth.hub_penalty 2 (the hub costs up to 4x that more) they spread over
    the other targets."""
    g, _ = small_graph(np.random.default_rng(1))
    hub = 70
    g = with_hub(g, hub, 0.5)
    visits = {}
    for h in (0.0, 2.0):
        gp, k = penalized_graph(g, hub_penalty=h)
        sp = SearchParams(use_constraints=False, beam_size=64, max_degree=24, temperature=0.05 * k)
        c = build_constraints(None, None, 200, FPS, sp)
        n = total = 0
        for seed in range(6):
            res = beam_search(gp, c, sp, seed=seed)
            p, at = res.path, res.synthetic_at or []
            n += sum(int(p[t] == hub) for t in at)
            total += len(at)
        visits[h] = (n, total)
    assert visits[0.0][0] >= 0.8 * visits[0.0][1] > 0
    assert visits[2.0][0] <= 0.2 * max(visits[2.0][1], 1)


def test_hub_penalty_is_off_in_the_paper_preset_and_on_in_quality():
    from convsynth_jax.config import default_params

    assert default_params([]).synth.hub_penalty == 0.0
    assert default_params(["preset=quality"]).synth.hub_penalty > 0


@pytest.mark.parametrize("bad", ["synth.hub_penalty=-1", "synth.hub_cap=0"])
def test_hub_options_reject_bad_values(bad):
    from convsynth_jax.config import default_params
    from convsynth_jax.errors import ConfigError

    with pytest.raises(ConfigError, match=bad.split("=")[0].split(".")[1]):
        default_params([bad])


def _speeds(n, spike_at=None):
    """joint_speeds-like dict: still hands and head, with a hand movement (both hands) at ``spike_at``."""
    sp = {k: np.full(n, 0.1) for k in ("LH", "RH", "Nod")}
    if spike_at is not None:
        for k in ("LH", "RH"):
            sp[k][spike_at:spike_at + 6] = 50.0
    return sp


def test_source_cooccurrence_reads_gestures_from_the_recordings_not_the_output():
    """A clause 1-2 s into a 3 s window. Played from a recording whose hands move inside the clause
    (as the ground truth is its own recording's), the source count matches window_counts on those
    speeds; played from a still recording, nothing matches, whatever the output's blends did."""
    import pandas as pd

    from convsynth_jax.config import default_params
    from convsynth_jax.evaluation.loo import source_window_cooccurrence
    from convsynth_jax.stats.cooccurrence import window_counts

    params = default_params([])
    fps, n = 30.0, 90
    own = pd.DataFrame([("PC", 1.0, 1.5, 2.0)], columns=["kind", "start", "peak", "end"])
    partner = pd.DataFrame(columns=["kind", "start", "peak", "end"])
    thr = {"LH": 1.0, "RH": 1.0, "Nod": 1.0}
    speeds = {"moving": _speeds(200, spike_at=140), "still": _speeds(200)}
    frames = np.arange(100, 100 + n)       # the recording's frames 100-189: the movement at 1.33 s
    gt = source_window_cooccurrence(["moving"] * n, frames, speeds, own, partner, fps, thr, params, "gt")
    ref = window_counts({k: v[100:100 + n] for k, v in speeds["moving"].items()}, own, partner, fps, thr,
                        params.annotate)
    assert {h: (gt[f"gt_{h}_matched"], gt[f"gt_{h}_total"]) for h in ref} == ref
    assert gt["gt_PC-LH/RH_matched"] == 1
    # a path cutting between two still recordings' frames every 10 frames
    clips = ["still" if (t // 10) % 2 else "moving" for t in range(n)]
    src = np.where((np.arange(n) // 10) % 2 == 1, 20 + np.arange(n), np.arange(n))   # "moving" frames 0-89: still
    syn = source_window_cooccurrence(clips, src, speeds, own, partner, fps, thr, params, "synth")
    assert syn["synth_PC-LH/RH_matched"] == 0 and syn["synth_PC-LH/RH_total"] == 1
