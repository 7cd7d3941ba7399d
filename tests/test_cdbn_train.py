"""CDBN training: LBG, Gaussian KL, merging, sparse structure, Eq. 8 and a planted recovery."""
from __future__ import annotations

import numpy as np
import pytest

from convsynth_jax.cdbn.cdbn import (
    gaussian_kl,
    merge_states,
    sparse_structure,
    train_cdbn,
    transition_distance,
)
from convsynth_jax.cdbn.em import e_step, make_batch
from convsynth_jax.cdbn.lbg import lbg
from convsynth_jax.cdbn.params import TrainParams
from convsynth_jax.cdbn.sampler import planted_cdbn, recovery_report, sample
from convsynth_jax.errors import CDBNError


def test_gaussian_kl_matches_monte_carlo_and_has_logdet_term():
    rng = np.random.default_rng(0)
    m0, m1 = rng.normal(size=3), rng.normal(size=3)
    a, b = rng.normal(size=(3, 3)), rng.normal(size=(3, 3))
    s0, s1 = a @ a.T + np.eye(3), b @ b.T + 0.5 * np.eye(3)
    x = rng.multivariate_normal(m0, s0, size=200_000)

    def logpdf(x, m, s):
        r = x - m
        return -0.5 * (np.einsum("ni,ij,nj->n", r, np.linalg.inv(s), r) + np.linalg.slogdet(s)[1] + 3 * np.log(2 * np.pi))

    mc = float(np.mean(logpdf(x, m0, s0) - logpdf(x, m1, s1)))
    assert abs(gaussian_kl(m0, s0, m1, s1) - mc) < 0.05
    # equal means, scaled covariance: only the trace and log-determinant terms differ from zero
    assert np.isclose(gaussian_kl(m0, s0, m0, 2 * s0), 0.5 * (1.5 - 3 + 3 * np.log(2)))
    assert gaussian_kl(m0, s0, m0, s0) == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("k", [3, 5, 6])
def test_lbg_finds_separated_clusters_for_non_powers_of_two(k):
    rng = np.random.default_rng(k)
    centres = rng.normal(0, 10, (k, 2))
    x = np.concatenate([c + rng.normal(0, 0.3, (200, 2)) for c in centres])
    cb, lab = lbg(x, k, TrainParams(), rng)
    assert cb.shape == (k, 2)
    d = np.linalg.norm(centres[:, None] - cb[None], axis=-1)
    assert np.all(d.min(axis=1) < 0.2)            # every true centre has a codeword next to it
    assert len(np.unique(lab)) == k


def test_merge_and_sparse_structure():
    from convsynth_jax.cdbn.params import DBNModel

    eye = np.eye(2)
    def model(means):
        K = len(means)
        return DBNModel(np.asarray(means, float), np.broadcast_to(eye, (K, 2, 2)).copy(), np.full((1, K), 1 / K),
                        np.full((1, K, K), 1 / K), (0,), (1,), ("a",))
    a = model([[0, 0], [10, 0]])
    b = model([[0.1, 0], [0, 10]])          # its first state is a's first state
    means, _covs, owners, origin, merges = merge_states([a, b], [np.ones(2) * 10, np.ones(2) * 10], 1.0)
    assert len(means) == 3 and len(merges) == 1
    assert origin[(0, 0)] == origin[(1, 0)]
    np.testing.assert_allclose(means[origin[(0, 0)]], [0.05, 0])
    owners = np.concatenate([owners, np.ones((1, 2), bool)])
    tmask, imask = sparse_structure(owners, 3)
    # under constraint a, b's exclusive state can only move to the shared state
    excl_b = origin[(1, 1)]
    assert tmask[0, excl_b].sum() == 1 and tmask[0, excl_b, 3]
    assert not imask[0, excl_b] and imask[1, excl_b]
    assert transition_distance(np.eye(3), np.full((3, 3), 1 / 3)) == pytest.approx(2 / 3)


def test_planted_cdbn_is_recovered():
    """A small planted case (3 constraints, N = 3, one state shared by two constraints, ~12k frames).
    The full acceptance run (60k frames, N = 4) is experiments/bench/bench_cdbn.py."""
    rng = np.random.default_rng(1)
    true, _owners = planted_cdbn(rng, num_constraints=3, states_per_constraint=3, speech_dim=3, motion_dim=2)
    tr = sample(true, rng, 24, 500)
    te = sample(true, rng, 8, 500)
    tm = train_cdbn(tr.observations, tr.constraints, 3, true.speech_dims, true.motion_dims,
                    TrainParams(max_iter=30, tol=1e-4), true.constraint_names)
    rep = recovery_report(true, tm.model)
    assert tm.model.num_states == true.num_states
    assert rep["states_recovered"] >= 0.9, rep
    assert rep["transition_linf"] < 0.1, rep
    # structural zeros of the trained model are exact and match the planted structure after matching
    perm = np.asarray(rep["perm"])
    np.testing.assert_array_equal(tm.model.transitions[:, perm][:, :, perm] > 0, true.transitions > 0)
    b = make_batch(te.observations, te.constraints)
    ll_true = e_step(true, b).log_likelihood / b.num_frames
    ll_est = e_step(tm.model, b).log_likelihood / b.num_frames
    assert abs(ll_est - ll_true) < 0.02 * abs(ll_true)
    assert tm.log_likelihoods[-1] > tm.log_likelihoods[0]
    # parameters: the Gaussians plus the free entries of the designed sparse structure
    from convsynth_jax.cdbn.params import num_parameters

    K = true.num_states
    dense = num_parameters(K, 3, 2)
    n_free = int((tm.transition_mask.sum(-1) - 1).sum() + (tm.initial_mask.sum(-1) - 1).sum())
    assert tm.num_parameters == K * (3 + 6 + 2 + 3) + n_free < dense * 3


def test_too_few_frames_per_state():
    rng = np.random.default_rng(2)
    x = [rng.normal(size=(12, 3))]
    c = [np.zeros(12, np.int32)]
    with pytest.raises(CDBNError, match="too few frames per state"):
        train_cdbn(x, c, 4, (0, 1), (2,), TrainParams(), ("other", "nod"))


def test_transition_distances_train_to_convergence(monkeypatch):
    """Eq. 8 (Sec. VII-B) compares converged models: transition_distances must train both options with
    CDBNEvalParams' distance_max_iter / distance_tol, not the cross-validation's max_iter (20), which left
    the shared model's fast states moving (0.13-0.18 instead of 0.016 on the nod/shake corpus). Also
    checks the common-rows variant on known matrices. Fails on the old code (no train override, the
    CDBN of the first test fold reused)."""
    from convsynth_jax.cdbn import experiment
    from convsynth_jax.cdbn.cdbn import TrainedModel
    from convsynth_jax.cdbn.params import CDBNParams, DBNModel

    K = 3
    shared_t = np.stack([np.full((K, K), 1 / 3)] * 3)
    shared_t[2, 0] = [0.5, 0.25, 0.25]                          # shake row 0 differs by 1/6
    sparse_t = np.zeros((3, K, K))
    sparse_t[1] = [[0.9, 0, 0.1], [0, 0, 1.0], [0.5, 0, 0.5]]   # state 1 is shake-only
    sparse_t[2] = [[0, 0, 1.0], [0, 0.8, 0.2], [0, 0.4, 0.6]]   # state 0 is nod-only, 2 shared
    owners = np.array([[1, 1, 0], [1, 0, 1], [1, 1, 1]], bool)
    seen = []

    def fake_fit(kind, turns, n, p, train=None):
        seen.append((kind, train))
        t = shared_t if kind == "shared" else sparse_t
        m = DBNModel(np.zeros((K, 2)), np.broadcast_to(np.eye(2), (K, 2, 2)), np.full((3, K), 1 / K), t,
                     (0,), (1,), ("other", "nod", "shake"))
        return TrainedModel(m, owners if kind == "cdbn" else np.ones((K, 3), bool), [0.0] * 7, kind)

    monkeypatch.setattr(experiment, "fit", fake_fit)
    ep = experiment.CDBNEvalParams(distance_max_iter=123, distance_tol=1e-5)
    d = experiment.transition_distances([], CDBNParams(), 8, ep)
    assert sorted(k for k, _ in seen) == ["cdbn", "shared"]
    assert all(t is not None and t.max_iter == 123 and t.tol == 1e-5 for _, t in seen)
    assert d["shared"] == pytest.approx(1 / 6)
    assert d["sparse"] == pytest.approx(0.9)                      # nod-only state 0: 0.9 self vs 0
    assert d["sparse_common_rows"] == pytest.approx(0.5)         # only the shared state row: |0.5 - 0|
    assert d["em_iterations"] == {"shared": 7, "cdbn": 7}


def test_transition_distances_warm_start_continues_the_given_cdbn(monkeypatch):
    """With a warm CDBN (the cross-validation's, same turns and N), the sparse Eq. 8 model continues EM
    from it with the distance settings (no second CDBN trained from LBG); the shared model is still
    trained; warm_start off trains both afresh. Fails on the old code (no ``warm`` argument)."""
    from convsynth_jax.cdbn import experiment
    from convsynth_jax.cdbn.cdbn import TrainedModel
    from convsynth_jax.cdbn.em import EMFit
    from convsynth_jax.cdbn.params import CDBNParams, DBNModel

    K = 3
    t = np.stack([np.full((K, K), 1 / 3)] * 3)
    m = DBNModel(np.zeros((K, 2)), np.broadcast_to(np.eye(2), (K, 2, 2)), np.full((3, K), 1 / K), t,
                 (0,), (1,), ("other", "nod", "shake"))
    warm = TrainedModel(m, np.ones((K, 3), bool), [0.0] * 20, "cdbn", [], t > 0, np.ones((3, K), bool))
    seen, cont = [], []

    def fake_fit(kind, turns, n, p, train=None):
        seen.append(kind)
        return TrainedModel(m, np.ones((K, 3), bool), [0.0] * 7, kind)

    def fake_fit_em(model, batch, params, max_iter=None, progress=False):
        cont.append((model, params))
        t2 = model.transitions.copy()
        t2[2, 0] = [0.5, 0.25, 0.25]
        return EMFit(model._replace(transitions=t2), [1.0] * 5, True, 5)

    monkeypatch.setattr(experiment, "fit", fake_fit)
    monkeypatch.setattr(experiment, "fit_em", fake_fit_em)
    monkeypatch.setattr(experiment, "make_batch", lambda *a, **k: None)
    ep = experiment.CDBNEvalParams(distance_max_iter=123, distance_tol=1e-5)
    d = experiment.transition_distances([], CDBNParams(), 8, ep, warm=warm)
    assert seen == ["shared"]
    assert len(cont) == 1 and cont[0][0] is m and cont[0][1].max_iter == 123 and cont[0][1].tol == 1e-5
    assert d["sparse"] == pytest.approx(1 / 6)                   # from the continued model
    assert d["em_iterations"]["cdbn"] == 25 and d["warm_started"]
    seen.clear()
    d = experiment.transition_distances([], CDBNParams(), 8, experiment.CDBNEvalParams(distance_warm_start=False),
                                        warm=warm)
    assert sorted(seen) == ["cdbn", "shared"] and not d["warm_started"]
