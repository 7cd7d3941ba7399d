"""The CDBN hand stream (cdbn/hands.py): 10-D arm/forearm features, their inverse, key-point
smoothing per joint, the hand model in system=cdbn (cdbn.stream=hands), and the real Bandai rig."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from convsynth_jax.cdbn.hands import (
    arm_angles,
    arm_quaternions,
    arm_rig,
    keypoint_smooth_joints,
    swing_of,
)
from convsynth_jax.cdbn.params import CDBNFeatureParams, num_parameters
from convsynth_jax.errors import CDBNError

BANDAI = Path(__file__).resolve().parent / "data" / "dataset-2_raise-up-right-hand_normal_016.bvh"


def test_swing_twist_against_a_plain_construction():
    """swing_of on r = S * T (S perpendicular to the axis, T about it) returns S."""
    rng = np.random.default_rng(0)
    axis = np.array([0.0, -1.0, 0.0])
    perp = rng.normal(size=(50, 3))
    perp -= (perp @ axis)[:, None] * axis
    perp *= (rng.uniform(0.1, 1.5, 50) / np.linalg.norm(perp, axis=1))[:, None]
    S = Rotation.from_rotvec(perp)
    T = Rotation.from_rotvec(rng.uniform(-1.2, 1.2, 50)[:, None] * axis)
    got = swing_of(S * T, axis)
    np.testing.assert_allclose((got * S.inv()).magnitude(), 0.0, atol=1e-9)


def test_features_round_trip_on_the_real_bandai_rig():
    from convsynth_jax.io.bvh import load_bvh

    mo = load_bvh(BANDAI)
    rig = arm_rig(mo.skeleton, CDBNFeatureParams())
    assert [mo.skeleton.names[j] for j in rig.joints] == ["UpperArm_L", "LowerArm_L", "UpperArm_R", "LowerArm_R"]
    a = arm_angles(mo, CDBNFeatureParams(), rig)
    assert a.shape == (mo.num_frames, 10) and np.isfinite(a).all()
    q = arm_quaternions(a, rig)
    for k, j in enumerate(rig.joints):
        want = Rotation.from_quat(np.asarray(mo.rotations[:, j], np.float64)[:, [1, 2, 3, 0]])
        have = Rotation.from_quat(q[:, k][:, [1, 2, 3, 0]])
        if k % 2 == 0:          # upper arm: exact
            np.testing.assert_allclose((have * want.inv()).magnitude(), 0.0, atol=1e-6)
        else:                   # forearm: the swing (twist dropped); the wrist lands where it did
            axis = rig.axes[k // 2]
            np.testing.assert_allclose(have.apply(np.tile(axis, (len(q), 1))), want.apply(np.tile(axis, (len(q), 1))),
                                       atol=1e-6)
    # a right-hand raise moves the right arm far more than the left
    assert a[:, 5:8].std(0).sum() > 3 * a[:, 0:3].std(0).sum()
    assert num_parameters(12, 6, a.shape[1]) == 1247           # the paper's 12-state hand model


def test_missing_arm_joint_is_a_project_error():
    from convsynth_jax.io.bvh import load_bvh

    mo = load_bvh(BANDAI)
    with pytest.raises(CDBNError, match="no joint named any of"):
        arm_rig(mo.skeleton, CDBNFeatureParams(arm_joints=("Nope", "LowerArm_L", "UpperArm_R", "LowerArm_R")))


def test_keypoint_smoothing_keeps_key_frames_and_slerps_between():
    rng = np.random.default_rng(1)
    T = 61
    r = Rotation.from_rotvec(rng.normal(scale=0.5, size=(T * 2, 3)))
    q = r.as_quat()[:, [3, 0, 1, 2]].reshape(T, 2, 4)
    out = keypoint_smooth_joints(q, 30.0, 12.0)
    step = 30.0 / 12.0
    keys = np.unique(np.concatenate([np.round(np.arange(0, T - 1, step)).astype(int), [T - 1]]))
    for j in range(2):
        a = Rotation.from_quat(out[keys, j][:, [1, 2, 3, 0]])
        b = Rotation.from_quat(q[keys, j][:, [1, 2, 3, 0]])
        np.testing.assert_allclose((a * b.inv()).magnitude(), 0.0, atol=1e-9)
        # a frame between two keys lies on the great arc between them (plain slerp)
        k0, k1 = keys[3], keys[4]
        t = k0 + 1
        q0 = Rotation.from_quat(q[k0, j][[1, 2, 3, 0]])
        q1 = Rotation.from_quat(q[k1, j][[1, 2, 3, 0]])
        frac = (t - k0) / (k1 - k0)
        want = q0 * Rotation.from_rotvec(frac * (q0.inv() * q1).as_rotvec())
        got = Rotation.from_quat(out[t, j][[1, 2, 3, 0]])
        assert (got * want.inv()).magnitude() < 1e-9


def test_bandai_hand_turns_pair_real_motion_with_real_speech():
    from convsynth_jax.cdbn.hand_eval import BANDAI_CONSTRAINTS, bandai_hand_turns

    from conftest import shared_path

    wav = shared_path("speech", "acoustic_corpus.wav")
    turns, rig = bandai_hand_turns(BANDAI.parent, wav, CDBNFeatureParams())
    assert len(turns) >= 2 and rig.joints
    for t in turns:
        assert t.speech.shape == (len(t.motion), 6) and t.motion.shape[1] == 10
        assert np.isfinite(t.observations()).all()
        c = t.constraints
        gesture = t.name.split("_")[1]
        assert c[0] == 0 and c[-1] == 0 and set(np.unique(c)) == {0, BANDAI_CONSTRAINTS.index(gesture)}


def test_bandai_constraints_name_the_side_and_span_the_whole_gesture():
    """Each real raise clip's constraint names its gesture with its side (a pooled
    'raise' does not say which arm to lift), and its span holds the whole lift and lowering: every
    frame left 'other' is within 10% of the clip's largest excursion from rest, and the frames just
    inside the span are already away from rest. (A fixed 15% margin at each end left up to half the
    lift in 'other'.) The pooled, fixed-margin labelling stays available as an option."""
    from convsynth_jax.cdbn.hand_eval import BANDAI_POOLED_CONSTRAINTS, bandai_constraints, bandai_hand_turns

    from conftest import shared_path

    wav = shared_path("speech", "acoustic_corpus.wav")
    turns, _ = bandai_hand_turns(BANDAI.parent, wav, CDBNFeatureParams())
    names = bandai_constraints()
    assert {t.name.split("_")[1] for t in turns} == {"raise-up-right-hand", "raise-up-both-hands"}
    for t in turns:
        m = t.motion
        away = np.minimum(np.linalg.norm(m - m[0], axis=1), np.linalg.norm(m - m[-1], axis=1))
        inside = np.flatnonzero(t.constraints > 0)
        assert {names[k] for k in t.constraints[inside]} == {t.name.split("_")[1]}
        assert (np.diff(inside) == 1).all()
        assert (away[t.constraints == 0] <= 0.1 * away.max()).all()
        assert away[inside[0]] > 0.1 * away.max() and away[inside[-1]] > 0.1 * away.max()
    pooled, _ = bandai_hand_turns(BANDAI.parent, wav, CDBNFeatureParams(), gestures="pooled", span="fraction")
    for t in pooled:
        r = int(round(0.15 * len(t.motion)))
        assert set(np.unique(t.constraints[r:-r])) == {BANDAI_POOLED_CONSTRAINTS.index("raise")}
        assert not t.constraints[:r].any() and not t.constraints[-r:].any()


def test_gesture_accuracy_by_kind_ignores_the_side():
    from convsynth_jax.cdbn.hand_eval import accuracy_by_kind

    rows = [{"truth": "raise-up-left-hand", "predicted": "raise-up-right-hand"},
            {"truth": "raise-up-both-hands", "predicted": "wave-both-hands"},
            {"truth": "wave-left-hand", "predicted": "wave-left-hand"},
            {"truth": "wave-right-hand", "predicted": "other"}]
    assert accuracy_by_kind({"cdbn": rows}) == {"cdbn": {"raise": {"n": 2, "accuracy": 0.5},
                                                         "wave": {"n": 2, "accuracy": 0.5}}}


def test_present_constraints_drop_the_absent_ones():
    from convsynth_jax.cdbn.dataset import Turn
    from convsynth_jax.cdbn.hand_eval import BANDAI_CONSTRAINTS, present_constraints

    c = np.array([0, 2, 2, 0, 6, 6, 0])
    t = Turn("x", "s", np.zeros((7, 6)), np.zeros((7, 10)), c)
    (u,), names = present_constraints([t], BANDAI_CONSTRAINTS)
    assert names == ("other", BANDAI_CONSTRAINTS[2], BANDAI_CONSTRAINTS[6])
    assert u.constraints.tolist() == [0, 1, 1, 0, 2, 2, 0]
