"""Easing curves (convsynth_jax/easing.py): end points, monotonicity, and the blends that use them."""
import numpy as np
import pytest

from convsynth_jax.easing import EASES, cosine, linear, smootherstep, smoothstep


@pytest.mark.parametrize("name", sorted(EASES))
def test_each_ease_runs_from_0_to_1_monotonically(name):
    w = np.linspace(0.0, 1.0, 201)
    y = EASES[name](w)
    assert y[0] == pytest.approx(0.0, abs=1e-15) and y[-1] == pytest.approx(1.0, abs=1e-15)
    assert np.all(np.diff(y) >= -1e-15)


def test_formulas_and_end_slopes():
    w = np.linspace(0.0, 1.0, 11)
    np.testing.assert_allclose(smoothstep(w), 3 * w ** 2 - 2 * w ** 3, atol=1e-15)
    np.testing.assert_allclose(smootherstep(w), 6 * w ** 5 - 15 * w ** 4 + 10 * w ** 3, atol=1e-15)
    np.testing.assert_allclose(cosine(w), (1 - np.cos(np.pi * w)) / 2, atol=1e-15)
    assert linear(w) is w
    h = 1e-4   # zero slope at both ends for all but linear; smootherstep also has zero curvature
    for f in (smoothstep, smootherstep, cosine):
        assert f(h) / h < 1e-3 and (1 - f(1 - h)) / h < 1e-3
    assert smootherstep(h) / h ** 2 < 1e-3


def test_the_motion_graph_blend_and_the_splice_ramp_use_them():
    from convsynth_jax.synth.realize import blend_weight
    from convsynth_jax.walktalk.gestures import Phases
    from convsynth_jax.walktalk.splice import splice_weights

    for n in (4, 8, 24):
        for k in range(n):
            assert blend_weight(k, n) == cosine(k + 1, n + 1)
    ph = Phases(pb=2, pe=8, sb=9, peaks=(12,), se=14, rb=15, re=22)
    lin, eased = splice_weights(30, ph, "linear"), splice_weights(30, ph, "smootherstep")
    np.testing.assert_array_equal(eased, smootherstep(lin))
