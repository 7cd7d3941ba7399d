"""The field-standard metrics (convsynth_jax.evaluation.field) against their slow references
(convsynth_jax.testing.field_reference, scikit-learn's CCA) and the validity checks of docs/metrics.md."""
from __future__ import annotations

import numpy as np
import pytest

from convsynth_jax.evaluation.field import beat, cca, coverage, fgd, kinematic
from convsynth_jax.evaluation.field.params import BeatParams, CoverageParams, HistogramParams
from convsynth_jax.testing import field_reference as ref

FPS = 30.0


def _walk(rng, frames=90, joints=5, scale=1.0):
    return np.cumsum(rng.normal(0, scale, (frames, joints, 3)), axis=0)


def test_jerk_and_acceleration_match_reference():
    p = _walk(np.random.default_rng(0), 40, 4)
    assert kinematic.average_jerk(p, FPS) == pytest.approx(ref.average_derivative_loop(p, FPS, 3), rel=ref.RTOL)
    assert kinematic.average_acceleration(p, FPS) == pytest.approx(ref.average_derivative_loop(p, FPS, 2), rel=ref.RTOL)


def test_histogram_overflow_bin_and_hellinger_match_reference():
    rng = np.random.default_rng(1)
    v = rng.exponential(30.0, (200, 5))   # some speeds beyond the 100 units/s range
    hp = HistogramParams()
    h = kinematic.histogram(v, hp.speed_bin_width, hp.speed_max)
    assert np.array_equal(h, ref.histogram_loop(v, hp.speed_bin_width, hp.speed_max))
    assert h[-1] == np.sum(v >= 100.0) > 0 and h.sum() == v.size   # nothing dropped
    g = kinematic.histogram(rng.exponential(20.0, (200, 5)), hp.speed_bin_width, hp.speed_max)
    assert kinematic.hellinger(h, g) == pytest.approx(ref.hellinger_loop(h, g), rel=1e-9)
    assert kinematic.hellinger(h, h) == pytest.approx(0.0, abs=1e-7)


def test_cca_matches_scikit_learn():
    pytest.importorskip("sklearn")
    from sklearn.cross_decomposition import CCA

    rng = np.random.default_rng(2)
    z = rng.normal(size=(400, 1))
    x = np.hstack([z + 0.5 * rng.normal(size=(400, 1)), rng.normal(size=(400, 2))]) @ rng.normal(size=(3, 3))
    y = np.hstack([z + 0.8 * rng.normal(size=(400, 1)), rng.normal(size=(400, 1))]) @ rng.normal(size=(2, 2))
    fit = cca.fit_cca(x, y, ridge=0.0)
    u, v = CCA(n_components=1, scale=False, max_iter=5000, tol=1e-12).fit(x, y).transform(x, y)
    expected = abs(np.corrcoef(u[:, 0], v[:, 0])[0, 1])
    assert fit.rho == pytest.approx(expected, abs=ref.CCA_ATOL)
    assert abs(cca.projected_correlation(fit, x, y)) == pytest.approx(fit.rho, abs=1e-9)
    # the moments route gives the same correlation as the frames
    zz = np.hstack([x, y])
    r = cca.correlation_from_moments(len(zz), zz.sum(0), zz.T @ zz, fit.x_weights, fit.y_weights)
    assert r == pytest.approx(cca.projected_correlation(fit, x, y), abs=1e-9)


def test_fgd_matches_reference_and_is_zero_on_itself():
    rng = np.random.default_rng(3)
    a = rng.normal(size=(300, 6)) @ rng.normal(size=(6, 6))
    b = rng.normal(0.3, 1.2, size=(250, 6)) @ rng.normal(size=(6, 6))
    assert fgd.fgd(a, b) == pytest.approx(ref.frechet_loop(a, b), rel=ref.FGD_RTOL)
    assert fgd.frechet_distance_eig(*fgd.gaussian_stats(a), *fgd.gaussian_stats(b)) == pytest.approx(
        ref.frechet_loop(a, b), rel=ref.FGD_RTOL)
    assert fgd.fgd(a, a) == pytest.approx(0.0, abs=1e-8)


def test_fgd_eps_retry_on_singular_covariances():
    import warnings

    rng = np.random.default_rng(4)
    a = np.hstack([rng.normal(size=(50, 2)), np.zeros((50, 2))])   # rank-deficient covariances
    b = np.hstack([rng.normal(size=(50, 2)), np.zeros((50, 2))])
    with warnings.catch_warnings():
        warnings.simplefilter("error")    # the singular square root is retried, not passed on as a warning
        d = fgd.fgd(a, b, eps=1e-6)
    assert d == pytest.approx(ref.frechet_loop(a, b), rel=1e-3, abs=1e-4)


def _path_with_speed(speed, fps=FPS):
    """(F, 1, 3) positions moving along a fixed direction with the given speed profile (units/s)."""
    v = np.asarray(speed)[:, None] * np.array([0.6, 0.8, 0.0])
    return (np.cumsum(v, axis=0) / fps)[:, None, :]


def test_beat_consistency_matches_reference():
    rng = np.random.default_rng(5)
    t = np.arange(300) / FPS
    p = np.concatenate([_path_with_speed(2.0 + np.sin(2 * np.pi * f * t + k) + 0.2 * rng.normal(size=t.size))
                        for k, f in enumerate((0.7, 1.1, 0.4))]
                       + [_path_with_speed(1.0 + 0.9 * np.sin(2 * np.pi * 0.9 * t))], axis=1)  # its pauses fall below the threshold
    audio = np.sort(rng.uniform(0, 10, 25))
    bp = BeatParams()
    mb = beat.motion_beats(p, FPS, bp)
    assert all(len(m) for m in mb[:3])
    assert len(mb[3]) == 0   # its near-still pauses (speed ratio 0.1) are not beats
    mine = beat.beat_consistency(mb, audio, 10.0, bp)
    theirs = ref.beat_consistency_loop(p, FPS, audio, 10.0, bp.sigma, bp.order, bp.threshold, bp.trim)
    assert np.isfinite(mine) and mine == pytest.approx(theirs, rel=1e-12)


def test_beat_consistency_rewards_aligned_beats():
    t = np.arange(450) / FPS
    p = _path_with_speed(2.0 + np.cos(2 * np.pi * (t - 1.0) / 0.8))   # speed dips every 0.8 s
    pauses = np.arange(1.4, 15.0, 0.8)
    bp = BeatParams()
    mb = beat.motion_beats(p, FPS, bp)
    aligned = beat.beat_consistency(mb, pauses, 15.0, bp)
    shifted = beat.beat_consistency(mb, pauses + 0.4, 15.0, bp)
    assert aligned > 0.95 and shifted < 0.6


def test_l1_diversity_and_gesture_area_coverage_match_reference():
    rng = np.random.default_rng(6)
    parents = (-1, 0, 1, 1, 3)
    a, b = _walk(rng, 20, 5, 2.0), _walk(rng, 20, 5, 2.0)
    assert coverage.l1_diversity(a) == pytest.approx(ref.l1_diversity_loop(a), rel=ref.RTOL)
    cp = CoverageParams(cell=3.0)
    ca, cb = coverage.covered_cells(a, parents, cp), coverage.covered_cells(b, parents, cp)
    ra, rb = ref.covered_cells_loop(a, parents, 3.0), ref.covered_cells_loop(b, parents, 3.0)
    assert {tuple(c) for c in ca.tolist()} == ra
    assert coverage.dice(ca, cb) == pytest.approx(ref.dice_loop(ra, rb), rel=1e-12)
    assert coverage.dice(ca, ca) == 1.0


def test_still_frames_match_reference_and_threshold():
    rng = np.random.default_rng(3)
    pos = _walk(rng, frames=60, joints=4, scale=0.05)
    pos[20:35] = pos[20]                         # a held pose: still inside, moving at its edges
    got = kinematic.still_frames(pos, FPS, 2.0)
    assert got.tolist() == ref.still_frames_loop(pos.tolist(), FPS, 2.0)
    assert got[20:34].all() and not got[19] and not got[35]
    # frame-to-frame tremor around a held pose is motion, not stillness
    tremor = np.repeat(pos[:1], 30, axis=0) + 0.1 * (-1.0) ** np.arange(30)[:, None, None]
    assert not kinematic.still_frames(tremor, FPS).any()
    # a joint moving at 3 units/s along x: still at threshold 4, not at 2
    line = np.zeros((30, 1, 3))
    line[:, 0, 0] = np.arange(30) * 3.0 / FPS
    assert kinematic.still_frames(line, FPS, 4.0).all() and not kinematic.still_frames(line, FPS, 2.0).any()
    assert kinematic.still_frames(np.zeros((1, 2, 3)), FPS).tolist() == [False]
    with pytest.raises(ValueError, match="frames, joints, 3"):
        kinematic.still_frames(np.zeros((5, 3)), FPS)
