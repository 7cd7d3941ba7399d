"""Motion-graph construction (paper Section 6): features -> key states -> threshold from a fitted
distribution of c(i, i+k) -> synthetic transitions between key states below the threshold ->
original transitions -> largest strongly connected component.

Rules (all configurable under ``graph.``):
* w_v (``w_v: auto``): the mean of the position term over the mean of the velocity term of
  D(i, i+k-1), over every frame pair (i, i+k-1) inside one clip (a seeded sample of 50,000 pairs if
  there are more), so both terms weigh equally on the pairs that set the threshold.
* key states: audio-status changes (own or partner label; clip starts) plus adaptive keyframes
  (a keyframe whenever the accumulated weighted joint-position change crosses a multiple of a step;
  the step is bisected so that ``key_fraction`` of all frames are key states).
* threshold: the ``quantile`` of ``distribution`` (Johnson SB by default, ``auto`` = lowest RSS)
  fitted to c(i, i+k) over all clips (stats/fits.py); ``meta['fit_table']`` lists only that fit
  unless ``fit_all_candidates`` (ours) or ``auto`` (the task figure4 fits and plots them all).
* synthetic transitions i -> j: i and j key states, c(i, j) = D(i, j-1) < threshold, not
  (same clip and |i - (j-1)| <= ``min_gap_frames``); optional ``local_minima``, ``max_out_degree``.
* original transitions: consecutive frames of a clip, cost 0. Then the largest strongly connected
  component is kept and its states renumbered (CSR sorted by source, then target).
``meta`` records every choice (threshold, w_v and its rule, fit table, joint weights and names,
root-relative method) so a cost can be recomputed from the BVH files alone.
"""
from __future__ import annotations

import logging
import time
from typing import NamedTuple

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from ..errors import GraphError
from ..stats.fits import CANDIDATES, fit_distributions
from .cost import candidate_edges, scaled_features
from .database import MotionDatabase, build_database
from .keystates import key_states
from .params import FeatureParams, GraphParams
from .seams import apply_glitch_filter, apply_seam_filter
from .types import MotionGraph

log = logging.getLogger(__name__)

# The largest SCC keeping fewer than this share of the states means the threshold (small k, low
# quantile) left too few synthetic transitions: the graph is logged as a warning and marked in meta.
SCC_WARN_FRACTION = 0.5

def velocity_weight(db: MotionDatabase, params: GraphParams) -> float:
    """w_v of Eq. 3: ``params.w_v`` or, for ``auto`` (ours), the k-step mean-term ratio (auto_w_v)."""
    return auto_w_v(db, params.k, seed=params.seed) if str(params.w_v) == "auto" else float(params.w_v)


def fit_candidates(params: GraphParams) -> tuple:
    """The distributions fitted to c(i, i+k): every candidate for ``distribution: auto`` or with
    ``fit_all_candidates`` (ours, for the comparison in meta['fit_table']), else only the configured
    one. The threshold does not depend on the others (each fit is on the same seeded sample), so it
    is the same either way; fitting the six others (numerical fits) is most of the fit time."""
    d = str(params.distribution)
    return CANDIDATES if d == "auto" or params.fit_all_candidates or d not in CANDIDATES else (d,)


def k_step_pairs(db: MotionDatabase, k: int) -> tuple[np.ndarray, np.ndarray]:
    """(i, i + k - 1) for every frame i whose i + k lies in the same clip: the pose pairs of c(i, i+k)."""
    i = np.arange(db.num_frames)
    j = i + k
    ok = j < db.num_frames
    ok[ok] &= db.clip[j[ok]] == db.clip[i[ok]]
    return i[ok], j[ok] - 1


def k_step_costs(db: MotionDatabase, k: int, w_v: float, features: np.ndarray | None = None) -> np.ndarray:
    """c(i, i+k) = D(i, i+k-1) for every i whose i+k lies in the same clip (Figure 4's data), (n,)
    float64 (computed in float32 from the scaled features, like the edge kernel)."""
    a, b = k_step_pairs(db, k)
    if a.size == 0:
        return np.zeros(0)
    X = scaled_features(db.positions, db.velocities, db.weights, w_v) if features is None else features
    out = np.empty(a.size, np.float32)
    for s in range(0, a.size, 65536):
        d = X[a[s:s + 65536]] - X[b[s:s + 65536]]
        out[s:s + 65536] = np.sqrt(np.einsum("nmc,nmc->nm", d, d)).sum(-1)
    return out.astype(np.float64)


def auto_w_v(db: MotionDatabase, k: int = 3, n_pairs: int = 50000, seed: int = 0) -> float:
    """w_v so that the velocity term has the same scale as the position term on the pairs that set
    the threshold: the ratio of the means of d(p_i, p_{i+k-1}) and d(v_i, v_{i+k-1}) over (a sample
    of) the k-step pairs of every clip. Posture differences between distant frames do not enter."""
    rng = np.random.default_rng(seed)
    i = np.arange(db.num_frames)
    j = i + max(k - 1, 1)
    ok = j < db.num_frames
    ok[ok] &= db.clip[j[ok]] == db.clip[i[ok]]
    a, b = i[ok], j[ok]
    if a.size == 0:
        return 1.0
    if a.size > n_pairs:
        pick = rng.choice(a.size, n_pairs, replace=False)
        a, b = a[pick], b[pick]
    dp = np.linalg.norm(db.positions[a] - db.positions[b], axis=-1) @ db.weights
    dv = np.linalg.norm(db.velocities[a] - db.velocities[b], axis=-1) @ db.weights
    mv = float(np.mean(dv))
    return float(np.mean(dp) / mv) if mv > 0 else 1.0


def select_edges(db, keys, threshold, w_v, params, edge_fn=None, stats=None, features=None):
    """Synthetic transitions i -> j between key states with c(i, j) = D(i, j-1) < threshold, not
    between near neighbours of one clip. Returns (i, j, cost) (E,) arrays in a deterministic but
    unspecified order (:func:`assemble_graph` sorts)."""
    src = np.flatnonzero(keys)
    kj = src[db.frame[src] > 0]  # j-1 must be in the same clip
    w = db.weights.astype(np.float32)
    if edge_fn is None:
        a, b, c = candidate_edges(db.positions, db.velocities, w, w_v, src, kj - 1, db.clip, threshold,
                                  int(params.min_gap_frames), tile=int(params.tile),
                                  n_pivots=int(params.n_pivots), seed=int(params.seed), stats=stats,
                                  workers=params.workers, features=features,
                                  max_out_degree=None if params.local_minima else params.max_out_degree,
                                  max_edges=params.max_edges)
    else:
        a, b, c = edge_fn(db.positions, db.velocities, w, w_v, src, kj - 1, db.clip, threshold,
                          int(params.min_gap_frames))
    j = b + 1
    if params.local_minima:
        a, j, c = _local_minima(a, j, c)
    if params.max_out_degree:
        a, j, c = _cap_degree(a, j, c, int(params.max_out_degree))
    return a, j, c


def _local_minima(a, j, c):
    """Keep an edge only if no edge from a neighbouring source (+-1 frame) to a neighbouring target
    (+-1 frame) is cheaper (Kovar et al.'s local minima, on the key-state grid). Vectorized: edges
    are looked up by the key a * (n + 2) + j in a sorted array."""
    if a.size == 0:
        return a, j, c
    n = int(max(a.max(), j.max())) + 3
    key = (a + 1) * n + (j + 1)
    order = np.argsort(key, kind="stable")
    sk, sc = key[order], c[order]
    keep = np.ones(a.size, bool)
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            if not (dx or dy):
                continue
            q = key + dx * n + dy
            pos = np.minimum(np.searchsorted(sk, q), sk.size - 1)
            hit = sk[pos] == q
            keep &= ~(hit & (sc[pos] < c))
    return a[keep], j[keep], c[keep]


def _cap_degree(a, j, c, cap):
    """The ``cap`` cheapest synthetic transitions of every source (ties: lower target)."""
    from .cost import _keep_cheapest

    a, j, c = _keep_cheapest(a, j, c, cap)
    order = np.lexsort((j, a))
    return a[order], j[order], c[order]


def assemble_graph(db: MotionDatabase, keys, a, j, c, meta: dict) -> MotionGraph:
    """Original transitions + synthetic ones, then the largest strongly connected component."""
    n = db.num_frames
    t = np.arange(n - 1)
    orig = t[db.clip[t] == db.clip[t + 1]]
    rows = np.concatenate([orig, a])
    cols = np.concatenate([orig + 1, j])
    cost = np.concatenate([np.zeros(orig.size, np.float32), c.astype(np.float32)])
    syn = np.concatenate([np.zeros(orig.size, bool), np.ones(a.size, bool)])
    meta = dict(meta, num_states_before_scc=int(n), num_edges_before_scc=int(rows.size),
                num_synthetic_before_scc=int(a.size))
    # CSR by scipy's linear-time COO -> CSR conversion, carrying each edge's index (+1: no zeros)
    # as its value, then sorted within rows: that gives the (source, target) order of all edges
    # without a general O(E log E) sort. Since the renumbering of the kept states is increasing,
    # the kept edges stay sorted.
    adj = csr_matrix((np.arange(1, rows.size + 1, dtype=np.int64), (rows, cols)), shape=(n, n))
    adj.sort_indices()
    if adj.nnz != rows.size:
        raise GraphError(f"duplicate transitions in the edge list ({rows.size - adj.nnz})")
    order = adj.data - 1
    rows, cols, cost, syn = np.repeat(np.arange(n), np.diff(adj.indptr)), adj.indices, cost[order], syn[order]
    ncomp, labels = connected_components(adj, directed=True, connection="strong")
    sizes = np.bincount(labels)
    keep = labels == int(np.argmax(sizes))
    new_id = np.full(n, -1, np.int64)
    new_id[keep] = np.arange(int(keep.sum()))
    e = keep[rows] & keep[cols]
    r, cc, co, sy = new_id[rows[e]], new_id[cols[e]], cost[e], syn[e]
    S = int(keep.sum())
    indptr = np.concatenate([[0], np.cumsum(np.bincount(r, minlength=S))]).astype(np.int64)
    meta.update(num_states=S, num_edges=int(r.size), num_synthetic_edges=int(sy.sum()), num_components=int(ncomp),
                scc_warning=scc_warning(S, n, int(r.size), meta.get("k")))
    if meta["scc_warning"]:
        log.warning("%s", meta["scc_warning"])
    return MotionGraph(
        clip_names=db.clip_names, fps=db.fps, clip=db.clip[keep], frame=db.frame[keep],
        own_label=db.own.label[keep], own_start=db.own.seg_start[keep], own_end=db.own.seg_end[keep],
        own_peak=db.own.seg_peak[keep], partner_label=db.partner.label[keep],
        partner_start=db.partner.seg_start[keep], partner_end=db.partner.seg_end[keep], is_key=keys[keep],
        indptr=indptr, indices=cc.astype(np.int64), cost=co.astype(np.float32), synthetic=sy, meta=meta)


def scc_warning(kept_states: int, states: int, kept_edges: int, k=None) -> str:
    """A warning when the largest strongly connected component keeps under SCC_WARN_FRACTION of the
    states, else the empty string."""
    if states == 0 or kept_states >= SCC_WARN_FRACTION * states:
        return ""
    at_k = f" at k = {k}" if k is not None else ""
    return (f"the largest strongly connected component{at_k} keeps {kept_states} of {states} states "
            f"({100 * kept_states / states:.1f}%, under {100 * SCC_WARN_FRACTION:.0f}%) and {kept_edges} edges: too few "
            f"synthetic transitions fall below the threshold; raise graph.quantile or graph.k")


class ConstructionPlan(NamedTuple):
    """What the edge search needs, computed before it (deterministic for a database and params):
    w_v (Eq. 3), the key states and keyframe step, the scaled features X (N, M, 3) float32, the fit
    of c(i, i+k) and the threshold."""

    w_v: float
    keys: np.ndarray
    keyframe_step: float
    features: np.ndarray
    fit: object
    threshold: float


def construction_plan(db: MotionDatabase, params: GraphParams, timings: dict | None = None) -> ConstructionPlan:
    """w_v, key states, the k-step cost fit and the threshold: the stages before the edge search,
    shared by :func:`build_graph` and the sharded builder (graph/stream.py)."""
    p = params
    tm = timings if timings is not None else {}
    t0 = time.perf_counter()
    w_v = auto_w_v(db, p.k, seed=p.seed) if str(p.w_v) == "auto" else p.w_v
    tm["w_v_s"] = time.perf_counter() - t0
    t1 = time.perf_counter()
    keys, step = key_states(db, p.key_fraction, p.use_audio_keys)
    tm["key_states_s"] = time.perf_counter() - t1
    t1 = time.perf_counter()
    X = scaled_features(db.positions, db.velocities, db.weights, w_v)
    kc = k_step_costs(db, p.k, w_v, features=X)
    if kc.size < 10:
        raise GraphError(f"too few frame pairs ({kc.size}) to fit the c(i, i+{p.k}) distribution")
    fit = fit_distributions(kc, candidates=fit_candidates(p), choose=str(p.distribution), bins=p.fit_bins,
                            seed=p.seed)
    threshold = fit.quantile(p.quantile)
    tm["threshold_s"] = time.perf_counter() - t1
    return ConstructionPlan(float(w_v), keys, float(step), X, fit, float(threshold))


def construction_meta(db: MotionDatabase, params: GraphParams, plan: ConstructionPlan, kernel: dict) -> dict:
    """``MotionGraph.meta`` before the SCC: every choice of the construction."""
    p, fit, keys = params, plan.fit, plan.keys
    return {
        "k": p.k, "quantile": p.quantile, "distribution": fit.chosen,
        "distribution_params": list(fit.params), "threshold": float(plan.threshold), "w_v": float(plan.w_v),
        "w_v_rule": "mean d(p_i,p_i+k-1) / mean d(v_i,v_i+k-1) over k-step pairs" if str(p.w_v) == "auto" else "config",
        "fit_table": [{"distribution": r.distribution, "rss": float(r.rss), "params": list(r.params)}
                      for r in fit.table.itertuples()],
        "joint_names": list(db.joint_names), "joint_weights": [float(x) for x in db.weights],
        "key_fraction": float(keys.mean()), "num_key_states": int(keys.sum()), "keyframe_step": float(plan.keyframe_step),
        "num_frames": int(db.num_frames), "min_gap_frames": p.min_gap_frames, "kernel": kernel,
        **db.meta,
    }


def build_graph(db: MotionDatabase, params: GraphParams, edge_fn=None, timings: dict | None = None) -> MotionGraph:
    """The full construction on a database. ``edge_fn`` swaps the edge kernel (the reference
    builder passes the NumPy one). ``meta['seconds']`` is the construction wall time."""
    p = params
    t0 = time.perf_counter()
    tm = timings if timings is not None else {}
    plan = construction_plan(db, p, tm)
    keys, threshold, w_v = plan.keys, plan.threshold, plan.w_v
    t1 = time.perf_counter()
    kstats: dict = {}
    a, j, c = select_edges(db, keys, threshold, w_v, p, edge_fn=edge_fn, stats=kstats, features=plan.features)
    a, j, c = apply_seam_filter(db, a, j, c, p, meta=kstats)  # ours, off by default (graph/seams.py)
    a, j, c = apply_glitch_filter(db, a, j, c, p, meta=kstats)  # ours, off by default (graph/seams.py)
    tm["edges_s"] = time.perf_counter() - t1
    t1 = time.perf_counter()
    meta = construction_meta(db, p, plan, kstats)
    g = assemble_graph(db, keys, a, j, c, meta)
    tm["scc_s"] = time.perf_counter() - t1
    g.meta["seconds"] = time.perf_counter() - t0
    g.meta["timings"] = dict(tm)
    log.info("motion graph: %d frames, %d key states (%.2f%%), threshold %.4g (%s, k=%d, q=%.3f), w_v %.4g; "
             "%d synthetic candidates; after SCC %d states, %d edges; %.2f s",
             db.num_frames, meta["num_key_states"], 100 * meta["key_fraction"], threshold, plan.fit.chosen, meta["k"],
             meta["quantile"], w_v, a.size, g.num_states, g.num_edges, g.meta["seconds"])
    return g


def build_graph_from_clips(clips, graph: GraphParams, features: FeatureParams) -> MotionGraph:
    return build_graph(build_database(clips, features), graph)
