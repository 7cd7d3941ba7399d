"""Transition targets that represent the recordings (ours): how much a synthetic edge's target is a
hub of the graph.

With the paper's threshold rule (c(i, j) below a quantile of c(i, i+k)) the states near the mean pose
are close to many others, so they collect most synthetic in-edges: on the default corpus's
leave-one-out graphs a transition target has 29-48 synthetic in-edges where the average state has
2.5-4, and paths that follow the cheapest transitions converge on these near-mean poses (pose
variance 0.65 of the recordings'). :func:`hub_costs` prices that: a synthetic edge into state j costs
``weight x m x min(in(j) / mean in, cap)`` more, m the median synthetic edge cost, in(j) j's synthetic
in-degree and ``mean in`` the mean over all states (a uniform in-degree adds ``weight x m`` to every
synthetic edge; a hub with ``cap`` times the mean or more adds ``cap x weight x m``).
"""
from __future__ import annotations

import numpy as np


def synthetic_in_degree(graph) -> np.ndarray:
    """(S,) int64: each state's number of synthetic in-edges."""
    syn = np.asarray(graph.synthetic, bool)
    return np.bincount(np.asarray(graph.indices)[syn], minlength=graph.num_states).astype(np.int64)


def synthetic_out_degree(graph) -> np.ndarray:
    """(S,) int64: each state's number of synthetic out-edges."""
    syn = np.asarray(graph.synthetic, bool)
    src = np.repeat(np.arange(graph.num_states), np.diff(graph.indptr))
    return np.bincount(src[syn], minlength=graph.num_states).astype(np.int64)


HUB_ENDS = ("target", "both")


def hub_costs(graph, weight: float, cap: float, ends: str = "target") -> np.ndarray:
    """(E,) float64 extra cost of every edge: 0 on original edges, on a synthetic edge i -> j
    ``weight x m x min(in(j) / mean in, cap)`` (module docstring); ``ends="both"``: the mean of that
    relative degree and the source's, ``min(out(i) / mean out, cap)`` (a hub is also where most
    transitions leave from). ``weight <= 0`` or no synthetic edge: zeros."""
    if ends not in HUB_ENDS:
        raise ValueError(f"hub ends must be one of {HUB_ENDS}, got {ends!r}")
    syn = np.asarray(graph.synthetic, bool)
    out = np.zeros(syn.shape[0], np.float64)
    if float(weight) <= 0 or not syn.any():
        return out
    m = float(np.median(np.asarray(graph.cost, np.float64)[syn]))
    deg = synthetic_in_degree(graph)
    mean = deg.sum() / max(graph.num_states, 1)     # the same for in- and out-degrees
    rel = np.minimum(deg / mean, float(cap))[np.asarray(graph.indices)[syn]]
    if ends == "both":
        src = np.repeat(np.arange(graph.num_states), np.diff(graph.indptr))[syn]
        rel = 0.5 * (rel + np.minimum(synthetic_out_degree(graph) / mean, float(cap))[src])
    out[syn] = float(weight) * m * rel
    return out
