"""HMM kernels of the CDBN (forward-backward, filter, Viterbi, EM) against float64 NumPy references."""
from __future__ import annotations

import numpy as np
import pytest

from convsynth_jax.testing import cdbn_reference as ref
from convsynth_jax.cdbn.em import e_step, fit_em, m_step, make_batch
from convsynth_jax.cdbn.params import DBNModel, TrainParams, num_parameters
from tests.tolerances import enable_x64


def random_model(rng, K=4, C=2, ds=2, dm=2, sparse=True):
    D = ds + dm
    means = rng.normal(0, 1.5, (K, D))
    covs = np.zeros((K, D, D))
    for k in range(K):
        for dims in (range(ds), range(ds, D)):
            a = rng.normal(0, 0.5, (len(dims), len(dims)))
            covs[k][np.ix_(dims, dims)] = a @ a.T + 0.3 * np.eye(len(dims))
    trans = rng.dirichlet(np.ones(K), size=(C, K))
    init = rng.dirichlet(np.ones(K), size=C)
    if sparse:  # structural zeros, every row keeps its self transition
        mask = rng.random((C, K, K)) < 0.6
        mask |= np.eye(K, dtype=bool)[None]
        trans = trans * mask
        trans /= trans.sum(-1, keepdims=True)
        init[:, -1] = 0.0
        init /= init.sum(-1, keepdims=True)
    return DBNModel(means, covs, init, trans, tuple(range(ds)), tuple(range(ds, D)), tuple(f"c{i}" for i in range(C)))


def sample(rng, model, T):
    C, K = model.initial.shape
    c = np.repeat(rng.integers(0, C, size=T // 10 + 1), 10)[:T]
    q = np.zeros(T, int)
    q[0] = rng.choice(K, p=model.initial[c[0]])
    for t in range(1, T):
        q[t] = rng.choice(K, p=model.transitions[c[t]][q[t - 1]])
    x = np.stack([rng.multivariate_normal(model.means[k], model.covariances[k]) for k in q])
    return x, c


def test_parameter_counts_match_paper():
    # Sec. VIII-A, Tables IV-V: 7-state head jDBN (6-D prosody, 3-D head) 300; 12-state hand (10-D) 1247
    assert num_parameters(7, 6, 3) == 300
    assert num_parameters(12, 6, 10) == 1247
    # a masked (CDBN) count equals the dense one for a dense mask and is smaller for a sparse one
    dense = np.ones((1, 7, 7), bool)
    assert num_parameters(7, 6, 3, dense, np.ones((1, 7), bool)) == 300
    sparse = dense.copy()
    sparse[0, 0, 1:] = False
    assert num_parameters(7, 6, 3, sparse, np.ones((1, 7), bool)) == 300 - 6


@pytest.mark.parametrize("seed", [0, 1])
def test_smoother_filter_viterbi_match_reference(seed):
    from convsynth_jax.cdbn.hmm import batch_filter, batch_posterior, batch_smoothed, batch_viterbi

    rng = np.random.default_rng(seed)
    model = random_model(rng)
    seqs, cons = zip(*[sample(rng, model, T) for T in (37, 60, 11)])
    with enable_x64():
        import jax.numpy as jnp

        b = make_batch(seqs, cons, bucket=16, dtype=np.float64)
        args = (jnp.asarray(b.x, jnp.float64), jnp.asarray(b.constraints), jnp.asarray(b.lengths),
                jnp.asarray(model.means), jnp.asarray(model.covariances), jnp.asarray(model.initial),
                jnp.asarray(model.transitions))
        for dims in ((0, 1, 2, 3), (0, 1)):  # joint and speech-only emissions
            post = batch_posterior(*args, dims)
            smoothed = batch_smoothed(*args, dims)     # synthesis: gamma without the transition counts
            filt_ll, filt = batch_filter(*args, dims)
            paths, scores = batch_viterbi(*args, dims)
            for i, (x, c) in enumerate(zip(seqs, cons)):
                T = len(x)
                le = ref.log_emissions(x, model.means, model.covariances, dims)
                ll, f, s, xi = ref.forward_backward(model.initial, model.transitions, le, c)
                assert np.isclose(float(post.log_likelihood[i]), ll, rtol=ref.LOGLIK_RTOL)
                assert np.isclose(float(filt_ll[i]), ll, rtol=ref.LOGLIK_RTOL)
                np.testing.assert_allclose(np.asarray(post.smoothed[i, :T]), s, atol=ref.POSTERIOR_ATOL)
                np.testing.assert_allclose(np.asarray(smoothed[i, :T]), s, atol=ref.POSTERIOR_ATOL)
                np.testing.assert_allclose(np.asarray(post.filtered[i, :T]), f, atol=ref.POSTERIOR_ATOL)
                np.testing.assert_allclose(np.asarray(filt[i, :T]), f, atol=ref.POSTERIOR_ATOL)
                np.testing.assert_allclose(np.asarray(post.xi_sum[i]), xi, atol=ref.POSTERIOR_ATOL)
                path, score = ref.viterbi(model.initial, model.transitions, le, c)
                np.testing.assert_array_equal(np.asarray(paths[i, :T]), path)
                assert np.isclose(float(scores[i]), score, rtol=ref.LOGLIK_RTOL)
                # structural zeros get exactly zero expected counts
                assert np.all(np.asarray(post.xi_sum[i])[model.transitions == 0] == 0.0)


def test_packed_batch_matches_reference_per_sequence():
    """Several sequences back to back in one row (make_batch(pack=True)): posteriors of each segment,
    the summed log-likelihood, expected transitions (none across a reset) and the E-step statistics
    equal the float64 reference's and the unpacked batch's."""
    from convsynth_jax.cdbn.hmm import batch_posterior

    rng = np.random.default_rng(5)
    model = random_model(rng, K=4, C=3)
    seqs, cons = zip(*[sample(rng, model, T) for T in (40, 20, 30, 10, 14)])
    with enable_x64():
        import jax.numpy as jnp

        pb = make_batch(seqs, cons, bucket=64, dtype=np.float64, pack=True, pack_length=64)
        ub = make_batch(seqs, cons, bucket=64, dtype=np.float64)
        assert int((pb.lengths > 0).sum()) == 2 and pb.x.shape[1] == 64      # 5 sequences in 2 rows
        post = batch_posterior(jnp.asarray(pb.x), jnp.asarray(pb.constraints), jnp.asarray(pb.lengths),
                               jnp.asarray(model.means), jnp.asarray(model.covariances),
                               jnp.asarray(model.initial), jnp.asarray(model.transitions), (0, 1, 2, 3),
                               jnp.asarray(pb.resets))
        ll_tot, xi_tot, init_tot = 0.0, 0.0, np.zeros_like(model.initial)
        found = 0
        for x, c in zip(seqs, cons):
            le = ref.log_emissions(x, model.means, model.covariances, range(4))
            ll, _, s, xi = ref.forward_backward(model.initial, model.transitions, le, c)
            ll_tot, xi_tot = ll_tot + ll, xi_tot + xi
            init_tot[c[0]] += s[0]
            for r in range(pb.x.shape[0]):          # locate the segment in the packed rows
                for a in np.flatnonzero(pb.resets[r]):
                    if a + len(x) <= pb.lengths[r] and np.array_equal(pb.x[r, a:a + len(x)], x):
                        np.testing.assert_allclose(np.asarray(post.smoothed[r, a:a + len(x)]), s,
                                                   atol=ref.POSTERIOR_ATOL)
                        found += 1
        assert found == len(seqs)
        assert np.isclose(float(np.sum(post.log_likelihood)), ll_tot, rtol=ref.LOGLIK_RTOL)
        np.testing.assert_allclose(np.asarray(post.xi_sum).sum(0), xi_tot, atol=ref.POSTERIOR_ATOL)
        sp, su = e_step(model, pb), e_step(model, ub)
        assert np.isclose(sp.log_likelihood, ll_tot, rtol=ref.LOGLIK_RTOL)
        np.testing.assert_allclose(sp.initial, init_tot, atol=ref.POSTERIOR_ATOL)
        np.testing.assert_allclose(sp.transitions, xi_tot, atol=ref.POSTERIOR_ATOL)
        for a, b in zip(sp[1:], su[1:]):
            np.testing.assert_allclose(a, b, atol=1e-8)


def reference_m_step(model, seqs, cons, floor):
    """One EM update from the reference posteriors, by loops (floor not reached in this test)."""
    K, D = model.means.shape
    C = model.initial.shape[0]
    g_all, x_all, xi_tot, init = [], [], np.zeros((C, K, K)), np.zeros((C, K))
    for x, c in zip(seqs, cons):
        le = ref.log_emissions(x, model.means, model.covariances, range(D))
        _, _, s, xi = ref.forward_backward(model.initial, model.transitions, le, c)
        g_all.append(s)
        x_all.append(x)
        xi_tot += xi
        init[c[0]] += s[0]
    g, x = np.concatenate(g_all), np.concatenate(x_all)
    means = np.stack([(g[:, k:k + 1] * x).sum(0) / g[:, k].sum() for k in range(K)])
    covs = np.zeros((K, D, D))
    for k in range(K):
        r = x - means[k]
        full = (g[:, k, None, None] * r[:, :, None] * r[:, None, :]).sum(0) / g[:, k].sum()
        for dims in (model.speech_dims, model.motion_dims):
            ix = np.ix_(dims, dims)
            covs[k][ix] = full[ix]
    rows = xi_tot.sum(-1, keepdims=True)
    trans = np.where(rows > 1e-10, xi_tot / np.where(rows > 0, rows, 1), model.transitions)  # no counts: keep
    init = init / np.where(init.sum(-1, keepdims=True) > 0, init.sum(-1, keepdims=True), 1)
    return means, covs, trans, init


def test_em_step_matches_reference_and_likelihood_never_decreases():
    rng = np.random.default_rng(3)
    true = random_model(rng, K=3, C=2)
    seqs, cons = zip(*[sample(rng, true, T) for T in (80, 50, 120)])
    # start from a perturbed model that keeps the structural zeros
    start = true._replace(means=true.means + rng.normal(0, 0.5, true.means.shape))
    tp = TrainParams(covariance_floor=1e-6, tol=-np.inf)
    with enable_x64():
        b = make_batch(seqs, cons, bucket=16, dtype=np.float64)
        st = e_step(start, b)
        new = m_step(start, st, tp)
        means, covs, trans, init = reference_m_step(start, seqs, cons, tp.covariance_floor)
        np.testing.assert_allclose(new.means, means, atol=1e-6)
        np.testing.assert_allclose(new.covariances, covs, atol=1e-6)
        np.testing.assert_allclose(new.transitions, trans, atol=1e-6)
        both = init.sum(-1) > 0
        np.testing.assert_allclose(new.initial[both], init[both], atol=1e-6)
        assert np.all(new.transitions[true.transitions == 0] == 0.0)
        fit = fit_em(start, b, tp, max_iter=15)
    lls = np.asarray(fit.log_likelihoods)
    assert len(lls) == 15
    assert np.all(np.diff(lls) >= -ref.MONOTONE_ATOL), np.diff(lls)
    assert lls[-1] > lls[0] + 1e-3          # EM actually moved
    assert np.all(fit.model.transitions[true.transitions == 0] == 0.0)


def test_covariance_floor_warns_and_bounds_eigenvalues():
    rng = np.random.default_rng(4)
    model = random_model(rng, K=2, C=1, sparse=False)
    x = rng.normal(size=(200, 4))
    x[:, 3] = x[:, 2]  # motion stream singular
    b = make_batch([x], None)
    st = e_step(model, b)
    with pytest.warns(RuntimeWarning, match="floored"):
        new = m_step(model, st, TrainParams(covariance_floor=1e-3))
    for k in range(2):
        assert np.linalg.eigvalsh(new.covariances[k][2:, 2:]).min() >= 1e-3 - 1e-9


@pytest.mark.parametrize("posterior", ["smoother", "filter", "viterbi"])
def test_batched_state_posteriors_equal_the_per_turn_ones(posterior):
    """state_posteriors_batch (one padded call for all turns of a fold) gives each turn's
    state_posteriors (which the float64 reference test above covers)."""
    from convsynth_jax.cdbn.synthesize import state_posteriors, state_posteriors_batch

    rng = np.random.default_rng(6)
    model = random_model(rng, K=4, C=2)
    seqs, cons = zip(*[sample(rng, model, T) for T in (70, 15, 130)])
    speech = [x[:, :2] for x in seqs]
    many = state_posteriors_batch(model, speech, list(cons), posterior)
    for sp, c, g in zip(speech, cons, many):
        np.testing.assert_allclose(g, state_posteriors(model, sp, c, posterior), atol=1e-5)


def test_inert_padding_states_change_nothing():
    """pad_states (models of nearby K share a compiled shape): the padded model's smoother, Viterbi
    and E-step statistics restricted to the real states equal the unpadded model's, and the inert
    states get exactly zero posterior."""
    import jax.numpy as jnp

    from convsynth_jax.cdbn.hmm import batch_posterior, batch_viterbi, pad_states

    rng = np.random.default_rng(7)
    model = random_model(rng, K=5, C=2)
    seqs, cons = zip(*[sample(rng, model, T) for T in (50, 33)])
    b = make_batch(seqs, cons, bucket=16)
    padded = pad_states(model.means, model.covariances, model.initial, model.transitions)
    assert padded[0].shape[0] == 8 and padded[3].shape == (2, 8, 8)
    run = lambda f, ps: f(jnp.asarray(b.x), jnp.asarray(b.constraints), jnp.asarray(b.lengths),
                          *(jnp.asarray(a, jnp.float32) for a in ps), (0, 1, 2, 3))
    plain = (model.means, model.covariances, model.initial, model.transitions)
    p0, p1 = run(batch_posterior, plain), run(batch_posterior, padded)
    np.testing.assert_allclose(np.asarray(p1.log_likelihood), np.asarray(p0.log_likelihood), rtol=1e-6)
    np.testing.assert_allclose(np.asarray(p1.smoothed)[..., :5], np.asarray(p0.smoothed), atol=1e-6)
    assert np.all(np.asarray(p1.smoothed)[..., 5:] == 0.0) and np.all(np.asarray(p1.xi_sum)[:, :, 5:] == 0.0)
    np.testing.assert_array_equal(np.asarray(run(batch_viterbi, padded)[0]), np.asarray(run(batch_viterbi, plain)[0]))


@pytest.mark.parametrize("offset", [0.0, 50.0])
def test_float32_emissions_match_the_float64_reference(offset):
    """The float32 emission kernel (a quadratic-form expansion, see hmm.gaussian_log_density) against
    the float64 reference on ill-conditioned covariances (condition number 400, eigenvalues down to
    1e-2) and data far from the origin: relative error within float32 round-off of the result."""
    import jax.numpy as jnp

    from convsynth_jax.cdbn.hmm import gaussian_log_density

    rng = np.random.default_rng(3)
    K, d = 12, 9
    means = rng.normal(0, 1.5, (K, d)) + offset
    covs = np.zeros((K, d, d))
    for k in range(K):
        q, _ = np.linalg.qr(rng.normal(size=(d, d)))
        covs[k] = (q * np.geomspace(1e-2, 4.0, d)) @ q.T
    x = means[rng.integers(0, K, 500)] + rng.normal(0, 1.0, (500, d))
    want = ref.log_emissions(x, means, covs, tuple(range(d)))
    got = np.asarray(gaussian_log_density(jnp.asarray(x, jnp.float32), jnp.asarray(means, jnp.float32),
                                          jnp.asarray(covs, jnp.float32)))
    assert got.shape == (500, K) and np.all(np.isfinite(got))
    assert np.max(np.abs(got - want) / np.maximum(1.0, np.abs(want))) < 5e-5


def _jit(fun, **static):
    """A kernel helper of cdbn.hmm with its static keywords bound, jitted (the library calls it inside its
    jitted kernels): one compiled program instead of one per operation."""
    import functools

    import jax

    return jax.jit(functools.partial(fun, **static))


def _packed_terms(initial, transitions, log_liks, cons, T, rows, dtype):
    """Sequences (log emissions (T_i, K) and constraints) packed back to back into ``rows`` rows of T
    frames (resets at each start, padding after) -> the batch's TransitionTerms, flattened."""
    import jax
    import jax.numpy as jnp

    from convsynth_jax.cdbn.hmm import _smoother

    ll, cc, lengths, resets = _packed_rows(log_liks, cons, T, rows)
    f = jax.jit(jax.vmap(_smoother, in_axes=(None, None, 0, 0, 0, 0)))   # one program (as in the library), not op by op
    _, _, _, terms = f(jnp.asarray(initial, dtype), jnp.asarray(transitions, dtype), jnp.asarray(ll, dtype),
                       jnp.asarray(cc), jnp.asarray(lengths), jnp.asarray(resets))
    return jax.tree_util.tree_map(lambda a: a.reshape((rows * T,) + a.shape[2:]), terms)


@pytest.mark.parametrize("x64", [False, True])
@pytest.mark.parametrize("fast_span", [None, -np.inf])
def test_expected_transitions_match_reference(x64, fast_span):
    """hmm.expected_transitions (after the scans, over the flattened frames of a packed batch) against
    the float64 reference's xi summed over the sequences: a sparse 5-state model with 3 constraints
    padded with 3 inert states whose emissions are the best of all (so that unreachable states carry
    the largest beta), five sequences packed into two rows with resets (one of a single frame), an
    all-padding row; by the factorized sum (default) and by the exact log-space sum for every frame
    (fast_span=-inf). Structural zeros and the inert states get exactly 0. By default every frame here
    takes the factorized sum (the result equals fast_span=inf's), unreachable inert states included."""
    import contextlib

    import jax.numpy as jnp

    from convsynth_jax.cdbn.hmm import expected_transitions, pad_states

    rng = np.random.default_rng(8)
    model = random_model(rng, K=5, C=3)
    seqs, cons = zip(*[sample(rng, model, T) for T in (70, 25, 40, 9, 1)])
    les = [ref.log_emissions(x, model.means, model.covariances, range(4)) for x in seqs]
    want = sum(ref.forward_backward(model.initial, model.transitions, le, c)[3] for le, c in zip(les, cons))
    _, _, initial, trans = pad_states(model.means, model.covariances, model.initial, model.transitions)
    inert = [np.concatenate([le, np.full((len(le), 3), le.max() + 50.0)], axis=1) for le in les]
    with enable_x64() if x64 else contextlib.nullcontext():
        dtype = jnp.float64 if x64 else jnp.float32
        terms = _packed_terms(initial, trans, inert, cons, 96, 3, dtype)
        xi = _jit(expected_transitions)
        got = np.asarray(xi(terms, jnp.asarray(trans, dtype)) if fast_span is None
                         else xi(terms, jnp.asarray(trans, dtype), fast_span), np.float64)
        if fast_span is None:
            fast = np.asarray(xi(terms, jnp.asarray(trans, dtype), np.inf), np.float64)
            np.testing.assert_array_equal(got, fast)
    assert got.shape == (3, 8, 8)
    assert np.all(got[trans == 0] == 0.0) and np.all(got[:, 5:] == 0.0) and np.all(got[:, :, 5:] == 0.0)
    if x64:
        np.testing.assert_allclose(got[:, :5, :5], want, atol=ref.POSTERIOR_ATOL)
    else:
        np.testing.assert_allclose(got[:, :5, :5], want, rtol=ref.XI_FLOAT32_RTOL, atol=ref.XI_FLOAT32_ATOL)


def test_expected_transitions_across_a_structural_zero_float32():
    """alpha_{t-1} on state 0 and gamma_t on state 3 with a structural zero 0 -> 3: the transition into
    t is 2 -> 3 with alpha_{t-1,2} = e^-300 relative (or 0 -> 1 with b_1 = e^-300), which no float32
    factorization holds (s_t ~ 300). Those frames take the exact log-space sum: float32 counts equal
    the float64 reference's, packed with resets and padding; the factorized sum alone
    (fast_span=inf) loses the 2 -> 3 counts."""
    import jax.numpy as jnp

    from convsynth_jax.cdbn.hmm import expected_transitions

    A = np.array([[[0.5, 0.5, 0, 0], [0, 1.0, 0, 0], [0, 0, 0.5, 0.5], [0, 0, 0, 1.0]]])
    initial = np.array([[0.5, 0, 0.5, 0]])
    f0 = [0.0, -1000.0, -300.0, -1000.0]          # state 0 best, state 2 e^-300 below
    f1 = [-1000.0, -300.0, -1000.0, 0.0]          # state 3 best (unreachable from 0), state 1 e^-300 below
    les = [np.array([f0, f1]), np.array([f0, f1, f1]), np.array([f0, f0, f1, f1])]
    cons = [np.zeros(len(le), np.int32) for le in les]
    want = sum(ref.forward_backward(initial, A, le, c)[3] for le, c in zip(les, cons))
    assert want[0, 2, 3] > 0.4 and want[0, 0, 1] > 0.4      # both routes carry real mass
    terms = _packed_terms(initial, A, les, cons, 8, 3, jnp.float32)
    xi = _jit(expected_transitions)
    got = np.asarray(xi(terms, jnp.asarray(A, jnp.float32)), np.float64)
    np.testing.assert_allclose(got, want, rtol=ref.XI_FLOAT32_RTOL, atol=ref.XI_FLOAT32_ATOL)
    assert np.all(got[A == 0] == 0.0)
    fast_only = np.asarray(xi(terms, jnp.asarray(A, jnp.float32), np.inf), np.float64)
    assert not np.allclose(fast_only, want, rtol=ref.XI_FLOAT32_RTOL, atol=ref.XI_FLOAT32_ATOL)


def _packed_rows(log_liks, cons, T, rows):
    """Sequences packed back to back into ``rows`` rows of T frames: (log_lik, constraints, lengths,
    resets); padding frames get arbitrary emissions."""
    K = log_liks[0].shape[1]
    ll = np.full((rows, T, K), 7.0)
    cc = np.zeros((rows, T), np.int32)
    resets = np.zeros((rows, T), bool)
    resets[:, 0] = True
    lengths = np.zeros(rows, np.int32)
    r = 0
    for le, c in zip(log_liks, cons):
        if lengths[r] + len(le) > T:
            r += 1
        a = lengths[r]
        ll[r, a:a + len(le)], cc[r, a:a + len(le)], resets[r, a] = le, c, True
        lengths[r] += len(le)
    return ll, cc, lengths, resets


@pytest.mark.parametrize("x64", [False, True])
@pytest.mark.parametrize("products", ["adaptive", "exact"])
def test_batch_smoother_matches_reference(products, x64):
    """The batch smoother's fast scaled products (exact log-space steps at the frames at risk) and its
    exact log-space products against the float64 reference: a sparse 5-state model with 3 constraints
    padded with 3 inert states whose emissions are the best of all, sequences packed into rows with
    resets, one row of padding only; log-likelihoods, filtered and smoothed posteriors and the
    expected transitions (summed after the scans) per sequence."""
    import contextlib

    import jax
    import jax.numpy as jnp

    from convsynth_jax.cdbn.hmm import _batch_smoother, expected_transitions, pad_states

    rng = np.random.default_rng(11)
    model = random_model(rng, K=5, C=3)
    seqs, cons = zip(*[sample(rng, model, T) for T in (70, 25, 40, 9, 1, 55)])
    les = [ref.log_emissions(x, model.means, model.covariances, range(4)) for x in seqs]
    _, _, initial, trans = pad_states(model.means, model.covariances, model.initial, model.transitions)
    inert = [np.concatenate([le, np.full((len(le), 3), le.max() + 50.0)], axis=1) for le in les]
    ll, cc, lengths, resets = _packed_rows(inert, cons, 96, 4)
    with enable_x64() if x64 else contextlib.nullcontext():
        dt = jnp.float64 if x64 else jnp.float32
        lls, filt, smooth, terms = _jit(_batch_smoother, products=products)(
            jnp.asarray(initial, dt), jnp.asarray(trans, dt), jnp.asarray(ll, dt), jnp.asarray(cc),
            jnp.asarray(lengths), jnp.asarray(resets))
        xi = jax.jit(jax.vmap(expected_transitions, in_axes=(0, None)))(terms, jnp.asarray(trans, dt))
        lls, filt, smooth, xi = (np.asarray(a, np.float64) for a in (lls, filt, smooth, xi))
    patol = ref.POSTERIOR_ATOL if x64 else ref.POSTERIOR_FLOAT32_ATOL
    lrtol = ref.LOGLIK_RTOL if x64 else ref.LOGLIK_FLOAT32_RTOL
    row_ll, row_xi = np.zeros(4), np.zeros((4, 3, 5, 5))
    r, a = 0, 0
    for le, c in zip(les, cons):
        if a + len(le) > 96:
            r, a = r + 1, 0
        want_ll, f, s, x = ref.forward_backward(model.initial, model.transitions, le, c)
        np.testing.assert_allclose(filt[r, a:a + len(le), :5], f, atol=patol)
        np.testing.assert_allclose(smooth[r, a:a + len(le), :5], s, atol=patol)
        assert np.all(smooth[r, a:a + len(le), 5:] == 0.0)
        row_ll[r] += want_ll
        row_xi[r] += x
        a += len(le)
    np.testing.assert_allclose(lls, row_ll, rtol=lrtol)
    assert lls[3] == 0.0 and np.all(xi[3] == 0.0)
    np.testing.assert_allclose(xi[:, :, :5, :5], row_xi, rtol=ref.XI_FLOAT32_RTOL, atol=ref.XI_FLOAT32_ATOL)
    assert np.all(xi[:, trans == 0] == 0.0)


def test_fast_products_fall_back_across_a_structural_zero():
    """alpha_{t-1} on state 0 and the next emission best on state 3, reachable only through 2 -> 3 with
    alpha_{t-1,2} = e^-300 relative (or 0 -> 1 with b_1 = e^-300): the fast scaled product leaves state
    2 out, so the frame is at risk and takes the exact log-space step. The adaptive smoother equals the
    float64 reference in float32 (log-likelihoods, expected transitions) and the all-exact kernel's
    posteriors (float32 round-off of terms of size 300 exceeds the posterior tolerance for both); the
    fast products alone (no check) lose the 2 -> 3 route."""
    import jax
    import jax.numpy as jnp

    from convsynth_jax.cdbn.hmm import _batch_smoother, _fast_log_products, _fast_matrices, expected_transitions

    A = np.array([[[0.5, 0.5, 0, 0], [0, 1.0, 0, 0], [0, 0, 0.5, 0.5], [0, 0, 0, 1.0]]])
    initial = np.array([[0.5, 0, 0.5, 0]])
    f0 = [0.0, -1000.0, -300.0, -1000.0]
    f1 = [-1000.0, -300.0, -1000.0, 0.0]
    les = [np.array([f0, f1]), np.array([f0, f1, f1]), np.array([f0, f0, f1, f1])]
    cons = [np.zeros(len(le), np.int32) for le in les]
    want = [ref.forward_backward(initial, A, le, c) for le, c in zip(les, cons)]
    ll, cc, lengths, resets = _packed_rows(les, cons, 4, 3)
    f32 = lambda a: jnp.asarray(a, jnp.float32)
    _, at_risk = _fast_log_products(f32([[0.0, -np.inf, -300.0, -np.inf]]), _fast_matrices(f32(A), False),
                                    jnp.zeros(1, jnp.int32), False)
    assert bool(at_risk[0])
    got = {}
    xi_rows = jax.jit(jax.vmap(expected_transitions, in_axes=(0, None)))   # one program for the three
    for products in ("adaptive", "fast", "exact"):
        lls, _, smooth, terms = _jit(_batch_smoother, products=products)(
            f32(initial), f32(A), f32(ll), jnp.asarray(cc), jnp.asarray(lengths), jnp.asarray(resets))
        xi = xi_rows(terms, f32(A))
        got[products] = [np.asarray(a, np.float64) for a in (lls, smooth, xi)]
    lls, smooth, xi = got["adaptive"]
    for r, (w_ll, _, s, x) in enumerate(want):
        assert np.isclose(lls[r], w_ll, rtol=ref.LOGLIK_FLOAT32_RTOL)
        np.testing.assert_allclose(smooth[r, :len(s)], got["exact"][1][r, :len(s)], atol=ref.POSTERIOR_FLOAT32_ATOL)
        np.testing.assert_allclose(smooth[r, :len(s)], s, atol=50 * ref.POSTERIOR_FLOAT32_ATOL)
        np.testing.assert_allclose(xi[r], x, rtol=ref.XI_FLOAT32_RTOL, atol=ref.XI_FLOAT32_ATOL)
    lls_fast = got["fast"][0]
    assert not np.allclose(lls_fast, [w[0] for w in want], rtol=ref.LOGLIK_FLOAT32_RTOL)


def test_backward_sampled_state_paths_have_the_smoothed_marginals():
    """sample_state_path draws from P(q | speech, C): over many draws, the share of paths in each state
    at each frame is the smoother's posterior there (within sampling noise)."""
    from convsynth_jax.cdbn.synthesize import sample_state_path, state_posteriors

    rng = np.random.default_rng(8)
    model = random_model(rng, K=4, C=2)
    x, c = sample(rng, model, 25)
    speech = x[:, :2]
    filtered = state_posteriors(model, speech, c, "filter")
    smoothed = state_posteriors(model, speech, c, "smoother")
    n = 3000
    draws = np.stack([sample_state_path(model, filtered, c, rng) for _ in range(n)])
    share = np.stack([(draws == k).mean(axis=0) for k in range(4)], axis=1)
    assert np.abs(share - smoothed).max() < 4.5 * np.sqrt(0.25 / n)
    assert np.abs(share - filtered).max() > 0.1     # the filter alone is not what is drawn


def test_sampled_motion_averages_to_the_expected_motion():
    """sample_motion: the means along drawn state paths average to Eq. 4's expected motion under the
    smoother (the posterior mean), and the draws scatter around those means with the states' variance."""
    from convsynth_jax.cdbn.synthesize import expected_motion, sample_motion, state_posteriors

    rng = np.random.default_rng(9)
    model = random_model(rng, K=4, C=2)
    x, c = sample(rng, model, 20)
    speech = x[:, :2]
    n = 1500
    mus, draws = zip(*[sample_motion(model, speech, c, rng) for _ in range(n)])
    mus, draws = np.stack(mus), np.stack(draws)
    assert mus.shape == draws.shape == (n, 20, 2)
    target = expected_motion(model, state_posteriors(model, speech, c, "smoother"))
    spread = np.asarray(model.means)[:, 2:].std()
    assert np.abs(mus.mean(axis=0) - target).max() < 5 * spread / np.sqrt(n)
    resid = (draws - mus).reshape(-1, 2)
    var = np.einsum("k,kii->i", np.ones(4) / 4, np.asarray(model.covariances)[:, 2:, 2:])  # rough scale
    assert 0.3 * var.min() < resid.var(axis=0).min() and resid.var(axis=0).max() < 3 * var.max()
