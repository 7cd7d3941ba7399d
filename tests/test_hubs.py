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


def reference_hub_costs(g, weight, cap):
    """Edge by edge: count each state's synthetic in-edges, then price every synthetic edge."""
    deg = [0] * g.num_states
    for e in range(g.num_edges):
        if g.synthetic[e]:
            deg[int(g.indices[e])] += 1
    mean = sum(deg) / g.num_states
    m = float(np.median([float(c) for c, s in zip(g.cost, g.synthetic) if s]))
    return np.array([weight * m * min(deg[int(g.indices[e])] / mean, cap) if g.synthetic[e] else 0.0
                     for e in range(g.num_edges)])


def test_hub_costs_match_the_edge_by_edge_reference():
    g, _ = small_graph(np.random.default_rng(0))
    g = with_hub(g, 7, 0.5)
    deg = synthetic_in_degree(g)
    assert deg[7] > 20 * np.mean(deg)
    for weight, cap in ((1.0, 4.0), (2.5, 100.0), (0.0, 4.0), (5.0, 16.0)):
        assert np.allclose(hub_costs(g, weight, cap), reference_hub_costs(g, weight, cap))
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
