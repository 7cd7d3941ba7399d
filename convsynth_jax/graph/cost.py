"""Transition-cost kernels (paper Eq. 3-4) in JAX.

c(i, j) = D(i, j - 1) with the pose distance
    D(a, b) = sum_b w_b ||p_a[b] - p_b[b]|| + w_v sum_b w_b ||v_a[b] - v_b[b]||,
which is a metric (a weighted sum of Euclidean norms). The all-pairs search between key states is
done in fixed-size tiles (one compile, bounded memory); tiles whose pairs cannot pass the threshold
are skipped using the triangle inequality with a few pivot states:
    D(a, b) >= |D(a, r) - D(b, r)| for every pivot r,
so if the intervals of D(., r) over the two tiles are further apart than the threshold, no pair of
the tiles can be an edge.
"""
from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np


@jax.jit
def pair_distance(pa, va, pb, vb, w, w_v):
    """D between every a and every b. pa, va: (A, J, 3); pb, vb: (B, J, 3); w: (J,) -> (A, B)."""
    dp = jnp.sqrt(jnp.sum((pa[:, None] - pb[None]) ** 2, axis=-1) + 0.0)
    dv = jnp.sqrt(jnp.sum((va[:, None] - vb[None]) ** 2, axis=-1) + 0.0)
    return jnp.einsum("abj,j->ab", dp + w_v * dv, w)


@jax.jit
def aligned_distance(pa, va, pb, vb, w, w_v):
    """D(a_k, b_k) for aligned rows. (N, J, 3) x2 -> (N,)."""
    dp = jnp.linalg.norm(pa - pb, axis=-1)
    dv = jnp.linalg.norm(va - vb, axis=-1)
    return (dp + w_v * dv) @ w


@partial(jax.jit, static_argnames=())
def _tile_mask(pa, va, pb, vb, w, w_v, threshold, ia, jb, clip_a, clip_b, min_gap):
    """Costs of a tile and the mask of pairs that are edges (below threshold, not trivial neighbours)."""
    d = pair_distance(pa, va, pb, vb, w, w_v)
    same = clip_a[:, None] == clip_b[None, :]
    near = same & (jnp.abs(ia[:, None] - jb[None, :]) <= min_gap)
    valid = (ia[:, None] >= 0) & (jb[None, :] >= 0)
    return d, (d < threshold) & ~near & valid


def candidate_edges(P, V, w, w_v, src, dst_prev, clip, threshold, min_gap, tile=512, n_pivots=8, seed=0,
                    stats: dict | None = None):
    """All (a, b) with a in ``src`` and b in ``dst_prev`` (database frame indices) such that
    D(a, b) < threshold and not (same clip and |a - b| <= min_gap). Returns (a, b, cost) arrays.

    P, V: (N, J, 3) float32 features (joints with zero weight may be dropped by the caller).
    """
    P = jnp.asarray(P, jnp.float32)
    V = jnp.asarray(V, jnp.float32)
    w = jnp.asarray(w, jnp.float32)
    src = np.asarray(src, np.int64)
    dst = np.asarray(dst_prev, np.int64)
    clip = np.asarray(clip, np.int64)
    rng = np.random.default_rng(seed)
    # pivots: spread out (farthest-point sampling from a random start) for tight bounds
    cand = np.union1d(src, dst)
    piv = [int(rng.choice(cand))]
    dmin = np.full(cand.size, np.inf)
    for _ in range(max(0, n_pivots - 1)):
        d = np.asarray(pair_distance(P[cand], V[cand], P[piv[-1]][None], V[piv[-1]][None], w, w_v))[:, 0]
        dmin = np.minimum(dmin, d)
        piv.append(int(cand[int(np.argmax(dmin))]))
    piv = np.asarray(piv)
    Dp = lambda idx: np.asarray(pair_distance(P[idx], V[idx], P[piv], V[piv], w, w_v), np.float64)  # noqa: E731
    ds, dd = Dp(src), Dp(dst)
    so, do = np.argsort(ds[:, 0], kind="stable"), np.argsort(dd[:, 0], kind="stable")
    src, ds = src[so], ds[so]
    dst, dd = dst[do], dd[do]

    def tiles(idx, dvals):
        out = []
        for s in range(0, idx.size, tile):
            block = idx[s:s + tile]
            dv = dvals[s:s + tile]
            pad = tile - block.size
            ids = np.concatenate([block, np.full(pad, -1)])
            safe = np.where(ids >= 0, ids, 0)
            out.append((ids, safe, dv.min(0), dv.max(0)))
        return out

    ta, tb = tiles(src, ds), tiles(dst, dd)
    thr = float(threshold)
    A, B, C = [], [], []
    skipped = computed = 0
    w_v = jnp.float32(w_v)
    thr32 = jnp.float32(thr)
    gap = jnp.int32(min_gap)
    for ida, sa, lo_a, hi_a in ta:
        pa, va = P[sa], V[sa]
        ca = jnp.asarray(np.where(ida >= 0, clip[sa], -1), jnp.int32)
        ia = jnp.asarray(ida, jnp.int32)
        for idb, sb, lo_b, hi_b in tb:
            gap_lb = np.max(np.maximum(lo_a - hi_b, lo_b - hi_a))
            if gap_lb >= thr:
                skipped += 1
                continue
            computed += 1
            d, m = _tile_mask(pa, va, P[sb], V[sb], w, w_v, thr32, ia,
                              jnp.asarray(idb, jnp.int32), ca, jnp.asarray(np.where(idb >= 0, clip[sb], -2), jnp.int32), gap)
            m = np.asarray(m)
            if m.any():
                r, c = np.nonzero(m)
                A.append(ida[r]); B.append(idb[c]); C.append(np.asarray(d)[r, c])
    if stats is not None:
        stats.update({"tiles_computed": computed, "tiles_skipped": skipped, "tile": tile, "pivots": int(piv.size)})
    if not A:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.float32)
    return np.concatenate(A), np.concatenate(B), np.concatenate(C).astype(np.float32)
