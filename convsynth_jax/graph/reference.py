"""Slow, obvious NumPy (float64) reference for the edge kernel: one row of costs at a time."""
from __future__ import annotations

import numpy as np


def reference_edges(P, V, w, w_v, src, dst_prev, clip, threshold, min_gap):
    """Same contract as :func:`convsynth_jax.graph.cost.candidate_edges`, no pruning."""
    P = np.asarray(P, np.float64)
    V = np.asarray(V, np.float64)
    w = np.asarray(w, np.float64)
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


def build_graph_reference(db, cfg=None):
    from .build import build_graph

    return build_graph(db, cfg, edge_fn=reference_edges)
