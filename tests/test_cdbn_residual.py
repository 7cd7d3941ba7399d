"""The spectral residual (cdbn/residual.py, ours): a draw has the fitted clips' SD, correlation,
power spectrum and hence jerk."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import lfilter

from convsynth_jax.cdbn.residual import draw_residual, fit_residual_spectrum
from convsynth_jax.errors import CDBNError


def _jerk(x, fps):
    return float(np.linalg.norm(np.diff(x, n=3, axis=0), axis=1).mean() * fps ** 3)


def _clips(rng, n_clips=12, T=600):
    """Smooth, correlated 2-D clips: second-order low-pass noise (a head-like spectrum), the second
    feature half the first plus its own noise."""
    out = []
    for _ in range(n_clips):
        w = rng.standard_normal((T + 200, 2))
        x = lfilter([1.0], [1.0, -1.6, 0.68], w, axis=0)[200:]
        x[:, 1] = 0.5 * x[:, 0] + 0.3 * x[:, 1]
        out.append(x * [3.0, 1.0])
    return out


def test_a_draw_has_the_clips_sd_correlation_and_jerk():
    rng = np.random.default_rng(0)
    clips = _clips(rng)
    spec = fit_residual_spectrum(clips, [np.zeros_like(c) for c in clips], 30.0)
    x = np.concatenate([c - c.mean(0) for c in clips])
    draws = [draw_residual(spec, 600, rng) for _ in range(12)]
    y = np.concatenate(draws)
    np.testing.assert_allclose(y.std(0), x.std(0), rtol=0.1)
    assert abs(np.corrcoef(y.T)[0, 1] - np.corrcoef(x.T)[0, 1]) < 0.1
    for k in range(2):
        ratio = np.mean([_jerk(d[:, [k]], 30.0) for d in draws]) / np.mean([_jerk(c[:, [k]], 30.0) for c in clips])
        assert 0.85 < ratio < 1.15, (k, ratio)
    # white noise with the same SD (a per-frame draw from the Gaussian) has several times the jerk
    white = rng.standard_normal((600, 2)) * x.std(0)
    assert _jerk(white, 30.0) > 4 * np.mean([_jerk(c, 30.0) for c in clips])
    # deterministic given the generator; zero mean per window
    a = draw_residual(spec, 301, np.random.default_rng(5))
    np.testing.assert_array_equal(a, draw_residual(spec, 301, np.random.default_rng(5)))
    assert a.shape == (301, 2) and np.allclose(a.mean(0), 0, atol=1e-9)
    assert draw_residual(spec, 0, rng).shape == (0, 2) and draw_residual(spec, 2, rng).shape == (2, 2)


def test_only_the_missing_power_is_added():
    """Where the output already has the recordings' spectrum nothing is added; where it has more (a
    jumpy output), nothing is added at those frequencies either; where it has less, the difference."""
    rng = np.random.default_rng(1)
    clips = _clips(rng)
    same = fit_residual_spectrum(clips, _clips(np.random.default_rng(2)), 30.0)
    full = fit_residual_spectrum(clips, [np.zeros_like(c) for c in clips], 30.0)
    assert np.all(draw_residual(same, 600, rng).std(0) < 0.35 * draw_residual(full, 600, rng).std(0))
    jumpy = [rng.standard_normal(c.shape) * 10 for c in clips]   # white: more power than the clips above 5 Hz
    spec = fit_residual_spectrum(clips, jumpy, 30.0)
    high = spec.freqs > 5.0
    assert np.all(spec.psd[high] == 0) and spec.psd[~high].max() > 0
    half = fit_residual_spectrum(clips, [0.5 * c for c in clips], 30.0)
    np.testing.assert_allclose(half.psd[1:], 0.75 * full.psd[1:], rtol=1e-9)


def test_bad_residuals_are_refused():
    with pytest.raises(CDBNError, match="no training clip"):
        fit_residual_spectrum([np.zeros((5, 3))], [np.zeros((5, 3))], 30.0)
    with pytest.raises(CDBNError, match="finite"):
        fit_residual_spectrum([np.full((40, 3), np.nan)], [np.zeros((40, 3))], 30.0)
    with pytest.raises(CDBNError, match="outputs"):
        fit_residual_spectrum([np.zeros((40, 3))], [], 30.0)


def test_match_keypoint_rate_lowers_the_rate_only_for_an_output_jerkier_than_the_recordings():
    """cdbn.synth.match_jerk (ours): a smooth recording and an output that jumps between two state
    means every few frames (jerkier than the recording at the paper's 15/s) get a lower rate, at which
    the smoothed output is not jerkier; an output smoother than the recordings keeps the paper's 15/s."""
    from convsynth_jax.cdbn.features import head_rotation_from_quat
    from convsynth_jax.cdbn.synthesize import keypoint_smooth
    from convsynth_jax.systems.cdbn import _angular_jerk, match_keypoint_rate

    def smooth(a, r):
        return head_rotation_from_quat(keypoint_smooth(a, 30.0, r))

    rng = np.random.default_rng(3)
    t = np.arange(600) / 30.0
    rec = [np.stack([3 * np.sin(2 * np.pi * 0.5 * t + p), 2 * np.sin(2 * np.pi * 0.3 * t + p), np.sin(t + p)], 1)
           + 0.05 * rng.standard_normal((600, 3)) for p in rng.uniform(0, 6, 4)]
    jumpy = [np.repeat(rng.choice([-1.0, 1.0], size=(150, 3)), 4, axis=0) for _ in rec]
    assert _angular_jerk(smooth(jumpy[0], 15.0), 30.0) > _angular_jerk(rec[0], 30.0)
    r = match_keypoint_rate(rec, jumpy, 30.0, 15.0, smooth)
    assert 3.0 < r < 15.0
    target = np.mean([_angular_jerk(x, 30.0) for x in rec])
    assert np.mean([_angular_jerk(smooth(m, r), 30.0) for m in jumpy]) <= target
    calm = [0.5 * x for x in rec]
    assert match_keypoint_rate(rec, calm, 30.0, 15.0, smooth) == 15.0
