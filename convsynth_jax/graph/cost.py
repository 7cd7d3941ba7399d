"""Transition-cost kernels (paper Eq. 3-4) in JAX.

The transition cost from frame i to frame j compares pose i with pose j-1:
    c(i, j) = D(i, j - 1),
    D(a, b) = sum_b w_b ||p_a[b] - p_b[b]|| + w_v sum_b w_b ||v_a[b] - v_b[b]||.   # Eq. 3-4
Folding the weights into the features (x_m = w_b p[b] for the position rows, w_v w_b v[b] for the
velocity rows; see :func:`scaled_features`) turns D into a plain sum of M Euclidean norms,
    D(a, b) = sum_m ||x_a[m] - x_b[m]||,    x: (M, 3) per frame,
which is a metric. The all-pairs search between key states (``src`` x ``dst_prev``) is done in
fixed-size tiles (one compile per tile size, memory bounded by a tile), and whole tiles are skipped
with the triangle inequality through a few pivot frames r:
    D(a, b) >= |D(a, r) - D(b, r)|,
so if the intervals of D(., r) over two tiles are further apart than the threshold (for any pivot),
no pair of the tiles can be an edge. To make the tiles compact in that pivot space the frames are
ordered by a k-d split of their pivot distances (leaves of exactly ``tile`` frames).

Symmetry: D is symmetric, but the two sides differ (key states i vs frames j-1 before key states),
so the matrix src x dst_prev is not. When the two sets mostly coincide (e.g. every frame a key
state) the kernel computes the union once, upper-triangle tiles only, and reads each unordered pair
in both directions; it picks whichever of the two plans needs fewer pair evaluations.

Why the tile kernel is written as a loop over the M norms: on XLA:CPU the loop becomes a single
elementwise fusion over the (tile, tile) output that vectorizes along the last axis; the
broadcast-then-reduce form ``(A, B, M, 3) -> (A, B)`` measured about 10x slower on this machine.
Compaction of the surviving pairs is done on the host from the fixed-shape masked tile (XLA:CPU's
cumsum/scatter compaction, ``jnp.nonzero(size=...)``, cost 2-3x the distance computation itself).
"""
from __future__ import annotations

import logging
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from functools import partial

import jax
import jax.numpy as jnp
from jax import lax
import numpy as np

from .. import kernel_cache

log = logging.getLogger(__name__)

# relative safety margin on tile lower bounds (computed from float32 pivot distances)
BOUND_MARGIN = 1e-4
# compact the masked tiles of a dispatch batch together in the plain case (False: tile by tile,
# the slow path that tests/test_graph_cost.py compares against)
BATCHED_COMPACTION = True


def scaled_features(P, V, w, w_v, dtype=np.float32) -> np.ndarray:
    """Fold joint weights and w_v into the features: (N, J, 3) x2 -> (N, M, 3) ``dtype`` with
    M = 2 * (number of joints with positive weight that ever move). Joints with weight 0 or with
    constant features (the root, which is at the origin of the root-relative frame) contribute
    exactly 0 to every cost and are dropped."""
    P = np.asarray(P, dtype)
    V = np.asarray(V, dtype)
    w = np.asarray(w, np.float64)
    if len(P):
        moving = ((P.max(0) > P.min(0)).any(-1) | (V.max(0) != 0).any(-1) | (V.min(0) != 0).any(-1))
    else:
        moving = np.zeros(len(w), bool)
    live = np.flatnonzero((w > 0) & moving)
    out = np.empty((P.shape[0], 2 * live.size, 3), dtype)
    out[:, :live.size] = P[:, live] * w[live, None].astype(dtype)
    out[:, live.size:] = V[:, live] * (float(w_v) * w[live, None]).astype(dtype)
    return out


def _sum_of_norms(a, b):
    """D between every column of a and every column of b. a: (M, 3, A), b: (M, 3, B) -> (A, B).

    Written with ``lax`` primitives, unrolled over the 3 M coordinates (one elementwise fusion, see
    the module docstring): the same operations in the same order as the ``jnp`` form
    ``acc + sqrt(d0 * d0 + d1 * d1 + d2 * d2)`` (tests/test_graph_cost.py compares the two bit for
    bit), but about a third of the primitives, so tracing it (which the persistent compilation
    cache does not save) takes a few times less."""
    M, A, B = a.shape[0], a.shape[-1], b.shape[-1]
    a2, b2 = lax.reshape(a, (3 * M, A)), lax.reshape(b, (3 * M, B))
    acc = lax.full((A, B), 0, a.dtype)
    for m in range(M):
        s = None
        for c in range(3):
            d = lax.sub(lax.broadcast_in_dim(lax.index_in_dim(a2, 3 * m + c, 0, False), (A, B), (0,)),
                        lax.broadcast_in_dim(lax.index_in_dim(b2, 3 * m + c, 0, False), (A, B), (1,)))
            d = lax.mul(d, d)
            s = d if s is None else lax.add(s, d)
        acc = lax.add(acc, lax.sqrt(s))
    return acc


@jax.jit
def feature_distance(xa, xb):
    """D between every a and every b of scaled features. xa: (A, M, 3), xb: (B, M, 3) -> (A, B)."""
    return _sum_of_norms(jnp.transpose(xa, (1, 2, 0)), jnp.transpose(xb, (1, 2, 0)))


@jax.jit
def pair_distance(pa, va, pb, vb, w, w_v):
    """D (Eq. 3-4) between every a and every b from unscaled features.
    pa, va: (A, J, 3); pb, vb: (B, J, 3); w: (J,) joint weights; w_v scalar -> (A, B)."""
    wj = w[:, None]
    xa = jnp.concatenate([pa * wj, va * (w_v * wj)], axis=1)
    xb = jnp.concatenate([pb * wj, vb * (w_v * wj)], axis=1)
    return _sum_of_norms(jnp.transpose(xa, (1, 2, 0)), jnp.transpose(xb, (1, 2, 0)))


@jax.jit
def aligned_distance(pa, va, pb, vb, w, w_v):
    """D(a_k, b_k) for aligned rows. (N, J, 3) x4 -> (N,)."""
    dp = jnp.linalg.norm(pa - pb, axis=-1)
    dv = jnp.linalg.norm(va - vb, axis=-1)
    return (dp + w_v * dv) @ w


@jax.jit
def masked_tile_costs(XA, XB, IA, IB, CA, CB, pa, pb, threshold, min_gap):
    """One tile of candidate transitions: a-tile ``pa`` against b-tile ``pb``.

    XA: (nta, M, 3, T) scaled features of the a-side tiles, XB: (ntb, M, 3, T) of the b-side;
    IA: (nta, T), IB: (ntb, T) int32 database frame indices (-1 = padding); CA, CB: clip indices.
    Returns (T, T) float32: D(a, b) where D < threshold, a and b are real frames and not trivial
    neighbours (same clip, |a - b| <= min_gap); +inf elsewhere.
    """
    # the barrier keeps the tile gather out of the distance fusion (which must stay vectorized)
    xa, xb = jax.lax.optimization_barrier((XA[pa], XB[pb]))
    ia, ib = IA[pa], IB[pb]
    d = _sum_of_norms(xa, xb)
    near = (CA[pa][:, None] == CB[pb][None, :]) & (jnp.abs(ia[:, None] - ib[None, :]) <= min_gap)
    ok = (d < threshold) & ~near & (ia[:, None] >= 0) & (ib[None, :] >= 0)
    return jnp.where(ok, d, jnp.inf)


def _bucket(n: int, least: int = 256) -> int:
    """Padded size for n rows: the next power of two (at least ``least``), so kernels compile for
    few shapes however the database size varies (e.g. across leave-one-out folds)."""
    return max(least, 1 << int(np.ceil(np.log2(max(n, 1)))))


def _pad_rows(x: np.ndarray, size: int) -> np.ndarray:
    return np.concatenate([x, np.repeat(x[-1:], size - x.shape[0], axis=0)]) if size > x.shape[0] else x


def distances_to(X, idx, targets) -> np.ndarray:
    """(len(idx), len(targets)) float64 D between frames ``idx`` and frames ``targets`` of X,
    evaluated with rows padded to a bucket size (few compiles)."""
    xa = _pad_rows(X[idx], _bucket(len(idx)))
    xb = _pad_rows(X[targets], _bucket(len(targets), 8))
    return np.asarray(feature_distance(xa, xb), np.float64)[:len(idx), :len(targets)]


def farthest_point_pivots(X, cand, n_pivots, rng) -> np.ndarray:
    """Pivot frames spread out over ``cand`` (farthest-point sampling from a random start)."""
    return pivot_embedding(X, cand, n_pivots, rng)[0]


def pivot_embedding(X, cand, n_pivots, rng):
    """(:func:`farthest_point_pivots`, ``distances_to(X, cand, pivots)``): farthest-point sampling
    from a random start, all of it in one device call (:func:`_farthest_point_kernel`: one distance
    column per pivot, where the plain loop evaluates a padded block of 8 per pivot and then all
    pivots again). The same kernel arithmetic, so the same pivots and values as the plain loop
    (tests/test_graph_cost.py compares them exactly)."""
    n_pivots = int(n_pivots)
    if n_pivots <= 0:
        return np.zeros(0, np.int64), np.zeros((len(cand), 0))
    cand = np.asarray(cand)
    first = int(np.flatnonzero(cand == int(rng.choice(cand)))[0])  # the row of the random start
    xa = _pad_rows(X[cand], _bucket(len(cand)))
    rows, emb = kernel_cache.call(_farthest_point_kernel, "farthest_point",
                                  (xa, np.int32(len(cand)), np.int32(first)), {"n_pivots": n_pivots})
    piv = np.asarray(cand)[np.asarray(rows)[:n_pivots]].astype(np.int64)
    return piv, np.asarray(emb, np.float64)[:len(cand)]


@partial(jax.jit, static_argnames=("n_pivots",))
def _farthest_point_kernel(xa, n_valid, first, n_pivots):
    """Farthest-point sampling on the device. xa: (A, M, 3) scaled features of the candidates (rows
    at and after ``n_valid`` are padding, never picked); first: row of the first pivot. Returns
    (rows of the pivots (n_pivots + 1,) int32, the last one unused; D(candidate, pivot) (A, n_pivots))."""
    xt = jnp.transpose(xa, (1, 2, 0))
    A = xt.shape[-1]
    valid = lax.iota(jnp.int32, A) < n_valid

    def body(k, carry):
        rows, emb, dmin = carry
        d = _sum_of_norms(xt, lax.dynamic_slice_in_dim(xt, rows[k], 1, axis=2))  # (A, 1)
        emb = lax.dynamic_update_slice_in_dim(emb, d, k, axis=1)
        dmin = jnp.minimum(dmin, d[:, 0])
        rows = rows.at[k + 1].set(jnp.argmax(jnp.where(valid, dmin, -jnp.inf)).astype(jnp.int32))
        return rows, emb, dmin

    rows = jnp.zeros(n_pivots + 1, jnp.int32).at[0].set(first)
    init = (rows, jnp.zeros((A, n_pivots), xt.dtype), jnp.full((A,), jnp.inf, xt.dtype))
    rows, emb, _ = lax.fori_loop(0, n_pivots, body, init)
    return rows, emb


def kd_order(E: np.ndarray, leaf: int) -> np.ndarray:
    """Permutation of the rows of E (n, k) whose consecutive blocks of ``leaf`` rows are the leaves
    of a k-d tree (split on the widest coordinate, left part a multiple of ``leaf``)."""
    out, stack = [], [np.arange(E.shape[0])]
    while stack:
        idx = stack.pop()
        if idx.size <= leaf:
            out.append(idx)
            continue
        e = E[idx]
        dim = int(np.argmax(e.max(0) - e.min(0)))
        nl = leaf * int(np.ceil(idx.size / leaf / 2))
        o = np.argpartition(e[:, dim], nl - 1, kind="introselect")
        stack.append(idx[o[nl:]])
        stack.append(idx[o[:nl]])
    return np.concatenate(out) if out else np.zeros(0, np.int64)


@dataclass
class _Tiling:
    ids: np.ndarray      # (nt, T) frame indices, -1 padding
    x: jax.Array         # (nt, M, 3, T) scaled features
    i32: jax.Array       # (nt, T) int32 frame indices
    c32: jax.Array       # (nt, T) int32 clip indices (padding: -1)
    lo: np.ndarray       # (nt, n_pivots) min pivot distance over the tile
    hi: np.ndarray       # (nt, n_pivots) max


def _tiling(X, idx, emb, clip, tile) -> _Tiling:
    order = kd_order(emb, tile)
    idx, emb = idx[order], emb[order]
    nt = -(-idx.size // tile)
    pad = nt * tile - idx.size
    ids = np.concatenate([idx, np.full(pad, -1, idx.dtype)]).reshape(nt, tile)
    e = np.concatenate([emb, np.full((pad, emb.shape[1]), np.nan)]).reshape(nt, tile, -1)
    with np.errstate(all="ignore"):
        lo, hi = (np.nanmin(e, 1), np.nanmax(e, 1)) if e.shape[-1] else (np.zeros((nt, 0)),) * 2
    # the device stacks hold a power-of-two number of tiles (extra tiles are never referenced)
    stack = np.full((_bucket(nt, 1), tile), -1, idx.dtype)
    stack[:nt] = ids
    safe = np.where(stack >= 0, stack, idx[0])
    xt = np.ascontiguousarray(X[safe].transpose(0, 2, 3, 1))
    cl = np.where(stack >= 0, clip[safe], -1).astype(np.int32)
    put = jax.device_put   # (jnp.asarray compiles a conversion per shape)
    return _Tiling(ids, put(xt), put(stack.astype(np.int32)), put(cl), lo, hi)


def _tile_lower_bounds(ta: _Tiling, tb: _Tiling) -> np.ndarray:
    """(nta, ntb) lower bound of D over each pair of tiles (triangle inequality through pivots)."""
    gap = np.maximum(ta.lo[:, None] - tb.hi[None], tb.lo[None] - ta.hi[:, None])
    return np.maximum(gap.max(-1), 0.0) if gap.shape[-1] else np.zeros(gap.shape[:2])


def _keep_cheapest(a, b, c, cap):
    """Rows of (a, b, c) keeping for every source a its ``cap`` cheapest targets (ties: lower b)."""
    order = np.lexsort((b, c, a))
    a, b, c = a[order], b[order], c[order]
    first = np.r_[0, np.flatnonzero(a[1:] != a[:-1]) + 1]
    rank = np.arange(a.size) - np.repeat(first, np.diff(np.r_[first, a.size]))
    keep = rank < cap
    return a[keep], b[keep], c[keep]


class CheapestPerSource:
    """A table of each source's ``cap`` cheapest candidate transitions seen so far (``costs`` (R, cap),
    ``inf`` where empty; ``targets`` (R, cap), -1 where empty), updated tile by tile so that memory
    stays rows x cap however many candidates pass. Which of equal costs a full row keeps is
    unspecified; :func:`_keep_cheapest` on :meth:`edges` settles ties (lower target) when candidates of
    several tables are merged. Used by both candidate searches (:func:`candidate_edges`, the sharded
    ``graph.stream``)."""

    def __init__(self, rows: int, cap: int):
        self.cap = int(cap)
        self.costs = np.full((int(rows), self.cap), np.inf, np.float32)
        self.targets = np.full((int(rows), self.cap), -1, np.int64)

    def add(self, rows, costs: np.ndarray, targets: np.ndarray) -> None:
        """Merge candidates into the table rows ``rows`` (an index or a slice): ``costs`` (R, W) (``inf``:
        none), their target frames ``targets`` (W,) shared by every row or (R, W)."""
        targets = np.broadcast_to(targets, costs.shape)
        if self.cap < costs.shape[1]:     # each row's cap cheapest of the tile first
            cols = np.argpartition(costs, self.cap - 1, axis=1)[:, :self.cap]
            costs, targets = np.take_along_axis(costs, cols, 1), np.take_along_axis(targets, cols, 1)
        allc = np.concatenate([self.costs[rows], costs], 1)
        allb = np.concatenate([self.targets[rows], targets], 1)
        keep = np.argpartition(allc, self.cap - 1, axis=1)[:, :self.cap]
        self.costs[rows] = np.take_along_axis(allc, keep, 1)
        self.targets[rows] = np.take_along_axis(allb, keep, 1)

    def edges(self, sources: np.ndarray | None = None):
        """(a, b, cost) of the kept candidates, row by row; ``a`` is the row, or ``sources[row]``."""
        r, c = np.nonzero(self.costs < np.inf)
        return (r if sources is None else sources[r]), self.targets[r, c], self.costs[r, c]


def candidate_edges(P, V, w, w_v, src, dst_prev, clip, threshold, min_gap, tile=128, n_pivots=8, seed=0,
                    stats: dict | None = None, workers: int | None = None, symmetric: str | bool = "auto",
                    features: np.ndarray | None = None, max_out_degree: int | None = None,
                    max_edges: int | None = 50_000_000):
    """All (a, b) with a in ``src`` and b in ``dst_prev`` (database frame indices) such that
    D(a, b) < threshold and not (same clip and |a - b| <= min_gap). Returns (a, b, cost) arrays
    (int64, int64, float32) in no particular order.

    P, V: (N, J, 3) root-relative positions and velocities; w: (J,) joint weights; clip: (N,).
    tile: frames per tile side; n_pivots: pivots for the tile bounds; workers: host threads
    dispatching tiles (default: CPU count, at most 4); symmetric: "auto" (fewer pair evaluations
    wins), True or False. ``features``: the :func:`scaled_features` of (P, V, w, w_v) if the caller
    has them already. ``max_out_degree``: keep only the cheapest that many per source, applied while
    streaming over the tiles (memory stays about N * max_out_degree edges). ``max_edges``: capacity
    of the host edge buffer; exceeding it raises :class:`GraphError` (None: unbounded).
    ``stats`` receives tile counts, pairs evaluated and ``candidates_found`` (before any cap).
    """
    from ..errors import GraphError

    src = np.unique(np.asarray(src, np.int64))
    dst = np.unique(np.asarray(dst_prev, np.int64))
    clip = np.asarray(clip, np.int64)
    thr = float(threshold)
    empty = (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.float32))
    if src.size == 0 or dst.size == 0 or not thr > 0:
        if stats is not None:
            stats.update({"tiles_computed": 0, "tiles_skipped": 0, "tile": tile, "pivots": 0, "pairs_evaluated": 0,
                          "symmetric": False})
        return empty
    X = scaled_features(P, V, w, w_v) if features is None else np.asarray(features, np.float32)
    rng = np.random.default_rng(seed)
    union = np.union1d(src, dst)
    sym = bool(symmetric) if symmetric != "auto" else union.size ** 2 / 2 < src.size * dst.size
    if n_pivots > 0:
        piv, emb_all = pivot_embedding(X, union, n_pivots, rng)
    else:
        piv, emb_all = np.zeros(0, np.int64), np.zeros((union.size, 0))
    emb_of = lambda idx: emb_all[np.searchsorted(union, idx)]  # noqa: E731
    if sym:
        ta = tb = _tiling(X, union, emb_all, clip, tile)
    else:
        ta = _tiling(X, src, emb_of(src), clip, tile)
        tb = _tiling(X, dst, emb_of(dst), clip, tile)
    lb = _tile_lower_bounds(ta, tb)
    # float32 pivot distances: keep a margin so that no pair that could pass is skipped
    scale = float(np.nanmax(np.abs(emb_all))) if emb_all.size else 0.0
    live = lb < thr + BOUND_MARGIN * (thr + scale)
    if sym:
        live &= np.triu(np.ones_like(live))
    pairs = np.argwhere(live)
    n_total = int(np.triu(np.ones_like(live)).sum()) if sym else live.size
    if stats is not None:
        stats.update({"tiles_computed": int(pairs.shape[0]), "tiles_skipped": n_total - int(pairs.shape[0]),
                      "tile": int(tile), "pivots": int(piv.size), "symmetric": sym,
                      "pairs_evaluated": int(pairs.shape[0]) * tile * tile})
    thr32, gap32 = np.float32(thr), np.int32(min_gap)
    # the tile kernel through its stored executable (kernel_cache.py), its key computed once
    tile_costs = kernel_cache.compiled(masked_tile_costs, "masked_tile_costs",
                                       (ta.x, tb.x, ta.i32, tb.i32, ta.c32, tb.c32, np.int32(0), np.int32(0), thr32,
                                        gap32))
    in_src = np.zeros(clip.size, bool)
    in_src[src] = True
    in_dst = np.zeros(clip.size, bool)
    in_dst[dst] = True

    def dispatched(chunk, depth=16):
        """(tile pair, masked costs) with at most ``depth`` tiles in flight (bounded memory)."""
        for s in range(0, len(chunk), depth):
            batch = [(p, tile_costs(ta.x, tb.x, ta.i32, tb.i32, ta.c32, tb.c32, np.int32(p[0]), np.int32(p[1]),
                                    thr32, gap32)) for p in chunk[s:s + depth]]
            yield from batch

    cap = int(max_out_degree) if max_out_degree else None
    limit = max_edges if (max_edges and cap is None) else None
    found = [0] * 64  # candidates per worker (before any cap)
    overflow = []

    def views(pa, pb, m):
        """(masked costs, row frame ids, column frame ids) of one tile in every direction it serves:
        a -> b+1, and in the symmetric plan also the mirrored b -> a+1 of an off-diagonal tile."""
        ia, ib = ta.ids[pa], tb.ids[pb]
        if not sym:
            return [(m, ia, ib)]
        sa, sb = np.maximum(ia, 0), np.maximum(ib, 0)
        fw = in_src[sa][:, None] & in_dst[sb][None]
        out = [(m if fw.all() else np.where(fw, m, np.inf), ia, ib)]
        if pa != pb:
            bw = in_src[sb][:, None] & in_dst[sa][None]
            out.append((m.T if bw.all() else np.where(bw, m.T, np.inf), ib, ia))
        return out

    def work(k, chunk):
        """Candidates of the worker's tiles: a list of (a, b, cost), or with a cap the dense
        per-source table (:class:`CheapestPerSource`) updated tile by tile."""
        out = []
        if not cap and not sym and BATCHED_COMPACTION:
            return work_batched(k, chunk)
        if cap:
            best = CheapestPerSource(clip.size, cap)
        for (pa, pb), m in dispatched(chunk):
            if overflow:
                break
            for mm, ra, rb in views(pa, pb, np.asarray(m)):
                fin = mm < np.inf
                n = int(np.count_nonzero(fin))
                found[k] += n
                if n == 0:
                    continue
                if not cap:
                    r, c = np.nonzero(fin)
                    out.append((ra[r], rb[c], mm[r, c]))
                    continue
                rows = np.flatnonzero(fin.any(1))
                best.add(ra[rows], mm[rows], rb)
            if limit is not None and sum(found) > limit:
                overflow.append(sum(found))
                break
        if cap:
            out.append(best.edges())
        return out

    def work_batched(k, chunk, depth=16):
        """:func:`work` for the plain case (one direction, no cap): the masked tiles of one dispatch
        batch are compacted together (one host pass per batch instead of one per tile), in the
        same order as tile by tile."""
        out = []
        for s in range(0, len(chunk), depth):
            ps = chunk[s:s + depth]
            ms = [tile_costs(ta.x, tb.x, ta.i32, tb.i32, ta.c32, tb.c32, np.int32(pa), np.int32(pb), thr32, gap32)
                  for pa, pb in ps]
            if overflow:
                break
            stack = np.stack([np.asarray(m) for m in ms])
            t, r, c = np.nonzero(stack < np.inf)
            found[k] += int(t.size)
            if t.size:
                out.append((ta.ids[ps[t, 0], r], tb.ids[ps[t, 1], c], stack[t, r, c]))
            if limit is not None and sum(found) > limit:
                overflow.append(sum(found))
                break
        return out

    nw = max(1, min(workers or min(os.cpu_count() or 1, 4), pairs.shape[0] or 1, len(found)))
    chunks = [pairs[k::nw] for k in range(nw)]
    if nw == 1:
        parts = work(0, chunks[0])
    else:
        with ThreadPoolExecutor(nw) as ex:
            parts = [x for res in ex.map(work, range(nw), chunks) for x in res]
    if stats is not None:
        stats["candidates_found"] = int(sum(found))
    if overflow:
        raise GraphError(f"more than graph.max_edges={max_edges} candidate transitions (at least {overflow[0]}); "
                         "lower graph.key_fraction or graph.quantile, or set graph.max_out_degree")
    if not parts:
        return empty
    a = np.concatenate([p[0] for p in parts]).astype(np.int64)
    b = np.concatenate([p[1] for p in parts]).astype(np.int64)
    c = np.concatenate([p[2] for p in parts]).astype(np.float32)
    if cap:
        a, b, c = _keep_cheapest(a, b, c, cap)
    return a, b, c
