"""Transition-cost kernels (graph/cost.py) against the slow NumPy reference (convsynth_jax/testing/graph_reference.py).

Edge sets are compared exactly, except for pairs whose reference cost lies within a relative
THRESHOLD_TIE of the threshold (float32 vs float64 rounding may put them on either side).
"""
import numpy as np
import pytest

from convsynth_jax.graph.cost import (_tile_lower_bounds, _tiling, candidate_edges, distances_to, farthest_point_pivots,
                                     pivot_embedding,
                                      feature_distance, kd_order, masked_tile_costs, pair_distance,
                                      scaled_features)
from convsynth_jax.testing.graph_reference import reference_cost_matrix, reference_edges
from tolerances import COST_FLOAT32, COST_FLOAT64, THRESHOLD_TIE, enable_x64


def random_features(seed, n_clips=4, frames=90, joints=6):
    """Smooth random walks per clip (poses recur across clips, so there are real edges), a static
    root joint and one zero-weight joint. Returns P, V (N, J, 3) float32, w (J,), clip (N,)."""
    rng = np.random.default_rng(seed)
    P, V, C = [], [], []
    for c in range(n_clips):
        n = int(frames + rng.integers(-20, 20))
        steps = rng.normal(0, 0.05, (n, joints, 3)).cumsum(0) + rng.normal(0, 0.3, (1, joints, 3))
        steps[:, 0] = 0.0  # the root is at the origin of root-relative features
        P.append(steps)
        V.append(np.gradient(steps, axis=0) * 30.0)
        C.append(np.full(n, c))
    w = np.ones(joints)
    w[-1] = 0.0
    return (np.concatenate(P).astype(np.float32), np.concatenate(V).astype(np.float32), w,
            np.concatenate(C).astype(np.int64))


def edge_dict(a, b, c):
    return dict(zip(zip(a.tolist(), b.tolist()), np.asarray(c, np.float64).tolist()))


def assert_same_edges(fast, ref, thr):
    """Exactly the reference edges, pairs within the tie band of the threshold excluded; costs
    within float32 tolerance."""
    fa, ra = edge_dict(*fast), edge_dict(*ref)
    tie = THRESHOLD_TIE * thr
    ref_core = {e for e, c in ra.items() if abs(c - thr) > tie}
    fast_core = {e for e, c in fa.items() if abs(ra.get(e, c) - thr) > tie}
    assert ref_core <= set(fa), f"{len(ref_core - set(fa))} reference edges missing"
    assert fast_core <= set(ra), f"{len(fast_core - set(ra))} edges not in the reference"
    common = sorted(set(fa) & set(ra))
    assert common
    np.testing.assert_allclose([fa[e] for e in common], [ra[e] for e in common], rtol=COST_FLOAT32)


def test_scaled_features_reproduce_eq_3_4():
    P, V, w, clip = random_features(0, 2, 40)
    w = w * np.linspace(0.5, 1.5, w.size)
    X = scaled_features(P, V, w, 0.7)
    # the static root and the zero-weight joint are dropped: 2 * (J - 2) rows
    assert X.shape == (P.shape[0], 2 * (P.shape[1] - 2), 3)
    a, b = np.arange(0, 30), np.arange(10, 40)
    ref = reference_cost_matrix(P[a], V[a], P[b], V[b], w, 0.7)
    np.testing.assert_allclose(np.asarray(feature_distance(X[a], X[b])), ref, rtol=COST_FLOAT32)
    np.testing.assert_allclose(np.asarray(pair_distance(P[a], V[a], P[b], V[b], w.astype(np.float32), 0.7)), ref,
                               rtol=COST_FLOAT32)


def _sum_of_norms_jnp(a, b):
    """The kernel's previous, obvious jnp form of D between columns (M, 3, A) x (M, 3, B) -> (A, B)."""
    import jax.numpy as jnp

    acc = jnp.zeros((a.shape[-1], b.shape[-1]), a.dtype)
    for m in range(a.shape[0]):
        d0 = a[m, 0][:, None] - b[m, 0][None, :]
        d1 = a[m, 1][:, None] - b[m, 1][None, :]
        d2 = a[m, 2][:, None] - b[m, 2][None, :]
        acc = acc + jnp.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    return acc


@pytest.mark.parametrize("x64", [False, True])
def test_lax_sum_of_norms_is_bitwise_the_jnp_form(x64):
    """The lax-primitive kernel (cheaper to trace) computes exactly what the jnp form does, bit for
    bit, so graphs built with either are identical."""
    import contextlib

    import jax
    from convsynth_jax.graph.cost import _sum_of_norms

    rng = np.random.default_rng(5)
    with enable_x64() if x64 else contextlib.nullcontext():
        dt = np.float64 if x64 else np.float32
        a = rng.normal(0, 0.4, (7, 3, 37)).astype(dt)
        b = rng.normal(0, 0.4, (7, 3, 29)).astype(dt)
        fast = np.asarray(jax.jit(_sum_of_norms)(a, b))
        slow = np.asarray(jax.jit(_sum_of_norms_jnp)(a, b))
    assert fast.dtype == dt and fast.shape == (37, 29)
    assert np.array_equal(fast, slow)


def test_pair_distance_in_float64_matches_reference_tightly():
    import jax.numpy as jnp

    P, V, w, _ = random_features(8, 2, 40)
    a, b = np.arange(0, 60, 3), np.arange(1, 60, 4)
    P64, V64 = P.astype(np.float64), V.astype(np.float64)
    with enable_x64():
        d = np.asarray(pair_distance(*(jnp.asarray(x, jnp.float64) for x in (P64[a], V64[a], P64[b], V64[b], w)), 0.3))
    assert d.dtype == np.float64
    np.testing.assert_allclose(d, reference_cost_matrix(P64[a], V64[a], P64[b], V64[b], w, 0.3), rtol=COST_FLOAT64)


@pytest.mark.parametrize("seed,tile,workers,symmetric", [(0, 16, 1, False), (1, 32, 2, False), (2, 16, 2, True),
                                                         (3, 64, 1, "auto")])
def test_candidate_edges_equal_reference(seed, tile, workers, symmetric):
    P, V, w, clip = random_features(seed)
    rng = np.random.default_rng(100 + seed)
    n = P.shape[0]
    src = np.flatnonzero(rng.random(n) < 0.4)
    dst = np.flatnonzero(rng.random(n) < 0.4)
    all_costs = reference_edges(P, V, w, 0.2, src, dst, clip, np.inf, 5)[2]
    thr = float(np.quantile(all_costs, 0.08))
    ref = reference_edges(P, V, w, 0.2, src, dst, clip, thr, 5)
    stats = {}
    fast = candidate_edges(P, V, w, 0.2, src, dst, clip, thr, 5, tile=tile, n_pivots=4, workers=workers,
                           symmetric=symmetric, stats=stats)
    assert stats["symmetric"] == (symmetric is True)  # "auto": the rectangle is cheaper for these subsets
    assert_same_edges(fast, ref, thr)
    # no trivial neighbours within one clip
    a, b, _ = fast
    assert not np.any((clip[a] == clip[b]) & (np.abs(a - b) <= 5))


@pytest.mark.parametrize("workers", [1, 2])
def test_batched_compaction_equals_tile_by_tile(monkeypatch, workers):
    """The plain case compacts a dispatch batch of masked tiles at once; tile by tile (the slow
    path) gives the same arrays in the same order, and the same candidate count."""
    import convsynth_jax.graph.cost as cost

    P, V, w, clip = random_features(6, 5, 120)
    rng = np.random.default_rng(6)
    n = P.shape[0]
    src = np.flatnonzero(rng.random(n) < 0.5)
    dst = np.flatnonzero(rng.random(n) < 0.5)
    thr = float(np.quantile(reference_edges(P, V, w, 0.2, src, dst, clip, np.inf, 5)[2], 0.1))
    runs = []
    for batched in (True, False):
        monkeypatch.setattr(cost, "BATCHED_COMPACTION", batched)
        stats = {}
        runs.append((candidate_edges(P, V, w, 0.2, src, dst, clip, thr, 5, tile=16, n_pivots=4, workers=workers,
                                     symmetric=False, stats=stats), stats))
    (fast, fs), (slow, ss) = runs
    assert fs["tiles_computed"] > 16  # more than one dispatch batch
    assert fs == ss and fast[0].size > 0
    for x, y in zip(fast, slow):
        assert x.dtype == y.dtype
        np.testing.assert_array_equal(x, y)


def test_every_frame_a_candidate_uses_the_symmetric_plan():
    P, V, w, clip = random_features(4, 3, 70)
    n = P.shape[0]
    src = np.arange(n)
    starts = np.flatnonzero(np.r_[True, clip[1:] != clip[:-1]])
    dst = np.setdiff1d(src, starts) - 1  # j - 1 for every j that has a predecessor in its clip
    thr = float(np.quantile(reference_edges(P, V, w, 0.3, src[::7], dst[::7], clip, np.inf, 3)[2], 0.05))
    stats = {}
    fast = candidate_edges(P, V, w, 0.3, src, dst, clip, thr, 3, tile=32, n_pivots=6, stats=stats)
    assert stats["symmetric"] is True
    # the union is evaluated once: upper-triangle tiles only
    nt = -(-n // 32)
    assert stats["tiles_computed"] + stats["tiles_skipped"] == nt * (nt + 1) // 2
    assert_same_edges(fast, reference_edges(P, V, w, 0.3, src, dst, clip, thr, 3), thr)


def test_pivot_embedding_is_farthest_point_sampling_with_distances_to():
    """pivot_embedding (features copied to the device once) picks the pivots of the plain loop (one
    distances_to call per pivot) and returns the same distances, which match the NumPy reference."""
    P, V, w, clip = random_features(4, 5, 80)
    X = scaled_features(P, V, w, 0.2)
    cand = np.arange(3, P.shape[0], 2)
    rng = np.random.default_rng(4)
    piv = [int(rng.choice(cand))]
    dmin = np.full(cand.size, np.inf)
    for _ in range(5):
        dmin = np.minimum(dmin, distances_to(X, cand, [piv[-1]])[:, 0])
        piv.append(int(cand[int(np.argmax(dmin))]))
    got_piv, got_emb = pivot_embedding(X, cand, 6, np.random.default_rng(4))
    np.testing.assert_array_equal(got_piv, piv)
    np.testing.assert_array_equal(got_emb, distances_to(X, cand, np.asarray(piv)))
    D = reference_cost_matrix(P, V, P, V, w, 0.2)
    np.testing.assert_allclose(got_emb, D[np.ix_(cand, piv)], rtol=1e-4, atol=1e-4)


def test_tile_bounds_never_exceed_the_true_minimum_and_skip_tiles():
    P, V, w, clip = random_features(5, 6, 100)
    X = scaled_features(P, V, w, 0.2)
    rng = np.random.default_rng(0)
    idx = np.arange(P.shape[0])
    piv = farthest_point_pivots(X, idx, 6, rng)
    emb = np.asarray(feature_distance(X[idx], X[piv]), np.float64)
    t = _tiling(X, idx, emb, clip, 32)
    lb = _tile_lower_bounds(t, t)
    D = reference_cost_matrix(P, V, P, V, w, 0.2)
    for i in range(t.ids.shape[0]):
        for j in range(t.ids.shape[0]):
            a, b = t.ids[i][t.ids[i] >= 0], t.ids[j][t.ids[j] >= 0]
            assert lb[i, j] <= D[np.ix_(a, b)].min() * (1 + 1e-5) + 1e-4
    # a tight threshold skips tiles and stays exact
    thr = float(np.quantile(D, 0.01))
    stats = {}
    fast = candidate_edges(P, V, w, 0.2, idx, idx, clip, thr, 2, tile=32, n_pivots=6, stats=stats)
    assert stats["tiles_skipped"] > 0
    assert_same_edges(fast, reference_edges(P, V, w, 0.2, idx, idx, clip, thr, 2), thr)


@pytest.mark.parametrize("symmetric,cap", [(False, 3), (True, 2), (True, 40)])
def test_streaming_degree_cap_keeps_the_cheapest_per_source(symmetric, cap):
    P, V, w, clip = random_features(8, 3, 80)
    n = P.shape[0]
    src = np.arange(n)
    dst = np.arange(1, n)
    ra, rb, rc = reference_edges(P, V, w, 0.2, src, dst, clip, np.inf, 4)
    thr = float(np.quantile(rc, 0.2))
    ra, rb, rc = reference_edges(P, V, w, 0.2, src, dst, clip, thr, 4)
    stats = {}
    a, b, c = candidate_edges(P, V, w, 0.2, src, dst, clip, thr, 4, tile=32, n_pivots=4, symmetric=symmetric,
                              max_out_degree=cap, stats=stats, workers=2)
    assert stats["candidates_found"] == ra.size  # counted before the cap
    for s in np.unique(ra):
        ref = np.sort(rc[ra == s])[:cap]
        mine = np.sort(c[a == s])
        # the same cheapest costs (a tie at the boundary could swap targets, costs stay equal)
        np.testing.assert_allclose(mine, ref, rtol=COST_FLOAT32)
    assert set(np.unique(a)) == set(np.unique(ra))


def test_kd_order_is_a_permutation_with_tile_aligned_leaves():
    rng = np.random.default_rng(1)
    E = rng.normal(size=(203, 3))
    o = kd_order(E, 16)
    assert np.array_equal(np.sort(o), np.arange(203))
    # leaves are compact: the mean spread inside the tiles is well below the overall spread
    full = E.max(0) - E.min(0)
    spread = np.mean([(E[o[s:s + 16]].max(0) - E[o[s:s + 16]].min(0)).max() for s in range(0, 192, 16)])
    assert spread < 0.6 * full.max()


def test_masked_tile_kernel_in_float64_matches_reference_tightly():
    import jax.numpy as jnp

    P, V, w, clip = random_features(6, 2, 40)
    X = scaled_features(P.astype(np.float64), V.astype(np.float64), w, 0.4, dtype=np.float64)
    T = 24
    ia = np.r_[np.arange(0, 20), [-1] * 4].astype(np.int32)   # 4 padding rows
    ib = np.r_[np.arange(10, 34)].astype(np.int32)
    xa = X[np.maximum(ia, 0)].transpose(1, 2, 0)[None]
    xb = X[ib].transpose(1, 2, 0)[None]
    ca, cb = clip[np.maximum(ia, 0)].astype(np.int32)[None], clip[ib].astype(np.int32)[None]
    ref = reference_cost_matrix(P.astype(np.float64)[np.maximum(ia, 0)], V.astype(np.float64)[np.maximum(ia, 0)],
                                P.astype(np.float64)[ib], V.astype(np.float64)[ib], w, 0.4)
    thr = float(np.quantile(ref, 0.5))
    with enable_x64():
        m = np.asarray(masked_tile_costs(jnp.asarray(xa), jnp.asarray(xb), jnp.asarray(ia[None]), jnp.asarray(ib[None]),
                                         jnp.asarray(ca), jnp.asarray(cb), 0, 0, jnp.float64(thr), 3))
    assert m.dtype == np.float64 and m.shape == (T, T)
    near = (ca[0][:, None] == cb[0][None]) & (np.abs(ia[:, None] - ib[None]) <= 3)
    expect = np.where((ref < thr) & ~near & (ia[:, None] >= 0), ref, np.inf)
    assert np.array_equal(np.isfinite(m), np.isfinite(expect))
    np.testing.assert_allclose(m[np.isfinite(m)], expect[np.isfinite(expect)], rtol=COST_FLOAT64)


def test_empty_inputs_give_no_edges():
    P, V, w, clip = random_features(7, 1, 30)
    for src, dst, thr in ((np.arange(0), np.arange(10), 1.0), (np.arange(10), np.arange(10), 0.0)):
        a, b, c = candidate_edges(P, V, w, 0.2, src, dst, clip, thr, 1)
        assert a.size == b.size == c.size == 0


@pytest.mark.parametrize("cap", [1, 3, 9])
def test_cheapest_per_source_keeps_each_rows_cheapest_of_all_it_was_given(cap):
    """The per-source table both candidate searches use, against sorting every (row, target, cost) it
    was given: each row keeps its ``cap`` cheapest costs, each with a target it was given with. Tiles
    come as row indices or a slice of rows, with targets per column or per entry."""
    from convsynth_jax.graph.cost import CheapestPerSource

    rng = np.random.default_rng(cap)
    rows = 7
    table = CheapestPerSource(rows, cap)
    given = []
    for t in range(12):
        width = int(rng.integers(1, 12))
        if t % 3:
            r = np.sort(rng.choice(rows, size=int(rng.integers(1, rows + 1)), replace=False))
            where = r
        else:
            r0 = int(rng.integers(0, rows - 1))
            r = np.arange(r0, r0 + 2)
            where = slice(r0, r0 + 2)
        costs = rng.integers(0, 20, size=(r.size, width)).astype(np.float32)      # whole numbers: ties
        costs[rng.uniform(size=costs.shape) < 0.3] = np.inf
        targets = rng.integers(0, 1000, size=width) if t % 2 else rng.integers(0, 1000, size=(r.size, width))
        table.add(where, costs, targets)
        full = np.broadcast_to(targets, costs.shape)
        given += [(int(r[i]), int(full[i, j]), float(costs[i, j])) for i, j in zip(*np.nonzero(np.isfinite(costs)))]
    a, b, c = table.edges()
    sources = np.arange(100, 100 + rows)
    np.testing.assert_array_equal(table.edges(sources)[0], sources[a])
    for row in range(rows):
        assert sorted(c[a == row].tolist()) == sorted(x[2] for x in given if x[0] == row)[:cap], row
        assert all((row, int(tgt), float(cost)) in given for tgt, cost in zip(b[a == row], c[a == row]))
