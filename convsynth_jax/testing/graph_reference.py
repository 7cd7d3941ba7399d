"""Slow, obvious NumPy (float64) references for the transition-cost kernels and the builder.

Nothing here is tiled, pruned or jitted: one row of costs at a time, straight from Eq. 3-4.
"""
from __future__ import annotations

import numpy as np


def reference_cost_matrix(pa, va, pb, vb, w, w_v) -> np.ndarray:
    """D(a, b) = sum_b w_b ||p_a - p_b|| + w_v sum_b w_b ||v_a - v_b||  (Eq. 3-4), float64.
    pa, va: (A, J, 3); pb, vb: (B, J, 3); w: (J,) -> (A, B)."""
    pa, va, pb, vb = (np.asarray(x, np.float64) for x in (pa, va, pb, vb))
    w = np.asarray(w, np.float64)
    out = np.empty((pa.shape[0], pb.shape[0]))
    for r in range(pa.shape[0]):
        dp = np.sqrt(((pa[r][None] - pb) ** 2).sum(-1)) @ w
        dv = np.sqrt(((va[r][None] - vb) ** 2).sum(-1)) @ w
        out[r] = dp + w_v * dv
    return out


def reference_edges(P, V, w, w_v, src, dst_prev, clip, threshold, min_gap):
    """Same contract as :func:`convsynth_jax.graph.cost.candidate_edges`, no pruning: every (a, b)
    with a in src, b in dst_prev, D(a, b) < threshold and not (same clip, |a - b| <= min_gap)."""
    P = np.asarray(P, np.float64)
    V = np.asarray(V, np.float64)
    w = np.asarray(w, np.float64)
    clip = np.asarray(clip)
    dst = np.asarray(dst_prev)
    A, B, C = [], [], []
    for a in np.asarray(src):
        dp = np.sqrt(((P[a][None] - P[dst]) ** 2).sum(-1)) @ w
        dv = np.sqrt(((V[a][None] - V[dst]) ** 2).sum(-1)) @ w
        d = dp + w_v * dv
        ok = (d < threshold) & ~((clip[dst] == clip[a]) & (np.abs(dst - a) <= min_gap))
        A.append(np.full(ok.sum(), a)); B.append(dst[ok]); C.append(d[ok])
    if not A:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
    return np.concatenate(A).astype(np.int64), np.concatenate(B).astype(np.int64), np.concatenate(C)


def build_graph_reference(db, params):
    """The full construction with :func:`reference_edges` as the edge kernel (the other stages are
    shared with the fast builder, so thresholds and key states are identical)."""
    from ..graph.build import build_graph

    return build_graph(db, params, edge_fn=reference_edges)
