"""Measures over sets of windows (evaluation/field/window_sets.py) and a window's provenance
(evaluation/provenance.py): each against a case worked by hand, with a control where it must not move."""
import numpy as np
import pytest

from convsynth_jax.evaluation.field.fgd import fgd
from convsynth_jax.evaluation.field.window_sets import fgd_split, joint_std, pose_std_ratio, raw_features, single_poses
from convsynth_jax.evaluation.provenance import blend_mask, source_visits


def _windows(seed, n=12, T=60, P=4, scale=1.0, shift=0.0):
    rng = np.random.default_rng(seed)
    return [np.cumsum(rng.normal(size=(T, P, 3)), axis=0) * scale + shift for _ in range(n)]


def test_fgd_split_terms_add_up_and_a_shift_moves_only_the_mean_term():
    gt = _windows(0)
    same = fgd_split(gt, gt)
    assert same["fgd_raw"] == pytest.approx(0.0, abs=1e-6) and same["total_variance_ratio"] == pytest.approx(1.0)
    moved = fgd_split([w + np.array([2.0, 0.0, 0.0]) for w in gt], gt)
    # every joint moved by 2 units in x: every feature moves (root-relative windows keep the offset), the
    # covariances do not
    assert moved["fgd_mean_term"] > 1.0 and moved["fgd_cov_term"] == pytest.approx(0.0, abs=1e-6)
    assert moved["mean_pose_offset_max_cm"] == pytest.approx(2.0)
    other = fgd_split(_windows(1, scale=2.0), gt)
    assert other["fgd_raw"] == pytest.approx(other["fgd_mean_term"] + other["fgd_cov_term"])
    assert other["fgd_raw"] == pytest.approx(fgd(raw_features(_windows(1, scale=2.0)), raw_features(gt)), rel=1e-6)
    assert other["total_variance_ratio"] > 1.5


def test_pose_spread_ratio_and_single_poses():
    gt = _windows(2)
    assert pose_std_ratio(gt, gt) == pytest.approx(1.0)
    assert pose_std_ratio([w * 0.5 for w in gt], gt) == pytest.approx(0.5)
    x = np.concatenate(gt)
    assert joint_std(gt)[1] == pytest.approx(np.sqrt(sum(x[:, 1, a].var() for a in range(3))))
    sp = single_poses(gt, step=3)
    assert sp.shape == (12 * 20, 12) and np.array_equal(sp[1], gt[0][3].ravel())


def test_source_visits_and_blend_mask_on_a_hand_worked_window():
    # 4 s at 2 fps: clip a seconds 0-1, then clip b second 0, then clip a second 0 again (a revisit)
    clips = ["a"] * 4 + ["b"] * 2 + ["a"] * 2
    frames = [0, 1, 2, 3, 0, 1, 0, 1]
    v = source_visits(clips, frames, 2.0, np.array([1, 0, 0, 0, 0, 0, 0, 0], bool), np.full(8, 1.5))
    # cells a:0 (4 frames), a:1 (2), b:0 (2): entropy of (0.5, 0.25, 0.25) = 1.5 bits
    assert v["entropy_bits"] == pytest.approx(1.5)
    assert v["top_clip_share"] == pytest.approx(6 / 8) and v["revisited_seconds"] == 1
    assert v["source_still_share"] == pytest.approx(1 / 8) and v["source_speed_ratio"] == pytest.approx(1.5)
    one = source_visits(["a"] * 4, [0, 1, 2, 3], 2.0, np.zeros(4, bool), np.ones(4))
    assert one["revisited_seconds"] == 0 and one["entropy_bits"] == pytest.approx(1.0)
    assert blend_mask(10, [2, 8], 3).tolist() == [False, False, True, True, True, False, False, False, True, True]
    assert not blend_mask(5, [], 3).any()
