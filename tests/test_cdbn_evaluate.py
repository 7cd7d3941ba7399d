"""Evaluation statistics of the CDBN (CCA, Gaussian KLD, Dunn-Sidak, gesture classifier)."""
from __future__ import annotations

import numpy as np
from scipy import stats

from convsynth_jax.cdbn.evaluate import (
    cca,
    constraint_tests,
    dunn_sidak,
    gaussian_kld,
    gesture_classifier,
    gesture_features,
)


def test_cca_reduces_to_pearson_in_one_dimension_and_finds_a_hidden_direction():
    rng = np.random.default_rng(0)
    x = rng.normal(size=(2000, 1))
    y = 0.6 * x + 0.8 * rng.normal(size=(2000, 1))
    assert np.isclose(cca(x, y), abs(np.corrcoef(x[:, 0], y[:, 0])[0, 1]), atol=1e-6)
    # a shared latent seen through different mixtures: CCA ~ its correlation, above any single pair
    z = rng.normal(size=2000)
    X = np.stack([z + 0.3 * rng.normal(size=2000), rng.normal(size=2000), rng.normal(size=2000)], 1) @ rng.normal(size=(3, 3))
    Y = np.stack([z + 0.3 * rng.normal(size=2000), rng.normal(size=2000)], 1) @ rng.normal(size=(2, 2))
    best_pair = max(abs(np.corrcoef(X[:, i], Y[:, j])[0, 1]) for i in range(3) for j in range(2))
    assert cca(X, Y) > best_pair and abs(cca(X, Y) - 1 / 1.09) < 0.03
    assert cca(rng.normal(size=(5000, 3)), rng.normal(size=(5000, 3))) < 0.08


def test_cca_is_the_projects_one_cca_and_does_not_depend_on_units():
    """The CDBN's CCA and the field metrics' are one definition (``stats.cca``). Its ridge is relative to
    each block's variance: motion in metres scores as in centimetres (the CDBN's former absolute ridge of
    1e-6 moved this correlation by 4e-3 at a scale of 0.01)."""
    from convsynth_jax.evaluation.field.cca import fit_cca as field_fit_cca
    from convsynth_jax.stats.cca import fit_cca

    rng = np.random.default_rng(0)
    x = rng.normal(size=(100, 3))
    y = x @ rng.normal(size=(3, 3)) * 0.3 + rng.normal(size=(100, 3))
    assert field_fit_cca is fit_cca and cca(x, y) == fit_cca(x, y).rho
    assert abs(cca(0.01 * x, y) - cca(x, y)) < 1e-9


def test_gaussian_kld_zero_for_same_data_and_grows_with_shrunk_variance():
    rng = np.random.default_rng(1)
    x = rng.normal(size=(5000, 3))
    assert abs(gaussian_kld(x, x)) < 1e-9
    assert gaussian_kld(x, 0.3 * x) > gaussian_kld(x, 0.8 * x) > 0.0


def test_dunn_sidak_against_a_hand_computation():
    rng = np.random.default_rng(2)
    groups = [rng.normal(0, 1, 40), rng.normal(0.1, 1, 50), rng.normal(1.5, 1, 45)]
    out = {(i, j): p for i, j, p in dunn_sidak(groups)}
    data = np.concatenate(groups)
    r = stats.rankdata(data)
    n = len(data)
    idx = np.cumsum([0] + [len(g) for g in groups])
    mr = [r[idx[k]:idx[k + 1]].mean() for k in range(3)]
    for (i, j), p in out.items():
        se = np.sqrt(n * (n + 1) / 12 * (1 / len(groups[i]) + 1 / len(groups[j])))   # no ties
        raw = 2 * stats.norm.sf(abs(mr[i] - mr[j]) / se)
        assert np.isclose(p, 1 - (1 - raw) ** 3)
    assert out[(0, 2)] < 1e-4 and out[(0, 1)] > 0.05
    res = constraint_tests(data, np.repeat([0, 1, 2], [40, 50, 45]), ("a", "b", "c"))
    assert res["kruskal_p"] < 1e-4 and len(res["pairs"]) == 3


def test_gesture_classifier_separates_pitch_and_yaw_oscillations():
    t = np.arange(45) / 30.0
    rng = np.random.default_rng(3)

    def seg(p, y):
        return np.stack([p * np.sin(2 * np.pi * 3 * t), y * np.sin(2 * np.pi * 3 * t), 0 * t], 1) + rng.normal(0, 0.2, (45, 3))

    segs = [seg(8, 0) for _ in range(5)] + [seg(0, 8) for _ in range(5)] + [seg(0, 0) for _ in range(5)]
    clf = gesture_classifier(segs, ["nod"] * 5 + ["shake"] * 5 + ["other"] * 5, 30.0)
    pred = clf.predict(np.stack([gesture_features(s, 30.0) for s in (seg(6, 0), seg(0, 6), seg(0.1, 0.1))]))
    assert list(pred) == ["nod", "shake", "other"]


def test_gesture_segments_report_their_turns():
    """gesture_segments(sources=...) names the turn of every segment (the per-turn gesture
    predictions of the Table VI analogue), aligned with segments and labels."""
    from convsynth_jax.cdbn.dataset import Turn
    from convsynth_jax.cdbn.experiment import gesture_segments

    c1 = np.array([0] * 40 + [1] * 10 + [0] * 40 + [2] * 8)
    c2 = np.array([0] * 35 + [2] * 12)
    turns = [Turn(n, "s", np.zeros((len(c), 6)), np.zeros((len(c), 3)), c) for n, c in (("a", c1), ("b", c2))]
    src = []
    segs, labs = gesture_segments(turns, [t.motion for t in turns], ("other", "nod", "shake"), 30.0,
                                  np.random.default_rng(0), sources=src)
    assert len(src) == len(segs) == len(labs)
    assert [(n, lab) for n, lab in zip(src, labs) if lab != "other"] == [("a", "nod"), ("a", "shake"), ("b", "shake")]
    assert sorted(n for n, lab in zip(src, labs) if lab == "other") == ["a", "a", "b"]


def test_other_windows_stay_inside_their_run():
    """An 'other' window of gesture_segments lies inside its 'other' run: a run of 30-44 frames
    followed by a gesture gives no window that reaches into the gesture (windows are 20-44 frames)."""
    from convsynth_jax.cdbn.dataset import Turn
    from convsynth_jax.cdbn.experiment import gesture_segments

    c = np.array([0] * 31 + [1] * 20 + [0] * 33 + [2] * 20)
    turn = Turn("a", "s", np.zeros((len(c), 6)), c[:, None].astype(float).repeat(3, 1), c)
    rng = np.random.default_rng(0)
    for _ in range(20):
        segs, labs = gesture_segments([turn], [turn.motion], ("other", "nod", "shake"), 30.0, rng)
        others = [s for s, lab in zip(segs, labs) if lab == "other"]
        assert len(others) == 2 and all(len(s) >= 20 and not s.any() for s in others)
