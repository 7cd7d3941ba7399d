import jax.numpy as jnp
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from convsynth_jax.io import load_bvh
from convsynth_jax.kinematics import finite_difference, fk_kernel, forward_kinematics, pose_features
from convsynth_jax.skeleton import Motion, Skeleton
from tolerances import FK_FLOAT64, enable_x64


def fk_reference(motion: Motion) -> np.ndarray:
    """Slow, obvious float64 FK: loop over frames and joints with 3x3 matrices from scipy."""
    F, J = motion.num_frames, motion.skeleton.num_joints
    out = np.zeros((F, J, 3))
    for f in range(F):
        mats = [None] * J
        for j, p in enumerate(motion.skeleton.parents):
            local = Rotation.from_quat(motion.rotations[f, j][[1, 2, 3, 0]]).as_matrix()
            t = motion.translations[f, j]
            if p < 0:
                mats[j] = local
                out[f, j] = t
            else:
                mats[j] = mats[p] @ local
                out[f, j] = out[f, p] + mats[p] @ t
    return out


def random_motion(rng, frames=7, joints=6):
    parents = tuple([-1] + [int(rng.integers(0, j)) for j in range(1, joints)])
    skel = Skeleton(tuple(f"j{j}" for j in range(joints)), parents, rng.normal(0, 10, (joints, 3)),
                    tuple(("Zrotation", "Xrotation", "Yrotation") for _ in range(joints)))
    q = rng.normal(size=(frames, joints, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    t = np.broadcast_to(skel.offsets, (frames, joints, 3)).copy()
    t[:, 0] = rng.normal(0, 50, (frames, 3))
    return Motion(skel, q, t, 30.0)


def test_fk_matches_float64_reference_random():
    rng = np.random.default_rng(0)
    m = random_motion(rng)
    with enable_x64():
        pos, _ = fk_kernel(jnp.asarray(m.rotations, jnp.float64), jnp.asarray(m.translations, jnp.float64),
                           m.skeleton.parents)
        assert pos.dtype == jnp.float64
        np.testing.assert_allclose(np.asarray(pos), fk_reference(m), atol=FK_FLOAT64)


def test_fk_float32_close_on_real_fixture():
    from conftest import TEST_DATA

    m = load_bvh(sorted(TEST_DATA.glob("*.bvh"))[0])
    ref = fk_reference(m.slice(0, 10))
    np.testing.assert_allclose(np.asarray(forward_kinematics(m.slice(0, 10))), ref, atol=1e-3)
    with enable_x64():
        pos = forward_kinematics(m.slice(0, 10), dtype=jnp.float64)
        np.testing.assert_allclose(np.asarray(pos), ref, atol=FK_FLOAT64)


def test_root_relative_features_ignore_root_position_and_heading():
    rng = np.random.default_rng(1)
    m = random_motion(rng, frames=5)
    f1 = pose_features(m)
    turn = Rotation.from_euler("Y", 70, degrees=True)
    rot = m.rotations.copy()
    rot[:, 0] = (turn * Rotation.from_quat(rot[:, 0][:, [1, 2, 3, 0]])).as_quat()[:, [3, 0, 1, 2]]
    tr = m.translations.copy()
    tr[:, 0] = turn.apply(tr[:, 0]) + np.array([100.0, 0, -40])
    f2 = pose_features(Motion(m.skeleton, rot, tr, m.fps))
    np.testing.assert_allclose(np.asarray(f1.positions), np.asarray(f2.positions), atol=1e-3)
    # without yaw removal the heading change shows
    f3 = pose_features(Motion(m.skeleton, rot, tr, m.fps), remove_yaw=False)
    assert np.abs(np.asarray(f3.positions) - np.asarray(f1.positions)).max() > 1.0


def test_finite_difference_is_fps_aware():
    x = np.arange(10, dtype=np.float32)[:, None] * 2.0  # 2 units per frame
    np.testing.assert_allclose(np.asarray(finite_difference(x, 30.0)), 60.0, rtol=1e-6)
    np.testing.assert_allclose(np.asarray(finite_difference(x[:1], 30.0)), 0.0)


def test_joint_weights_zero_fingers():
    from convsynth_jax.data.skeleton_seated import seated_skeleton

    s = seated_skeleton()
    w = s.joint_weights()
    names = np.array(s.names)
    assert set(names[w == 0]) == {n for n in names if any(k in n for k in ("Thumb", "Index", "Middle"))}
    assert s.joint_weights(overrides={"Head": 2.0})[s.index("Head")] == 2.0


def test_numpy_fk_is_the_kernel_recursion_in_float64():
    """kinematics.global_transforms_np (the float64 path Walk the Talk takes) against the jitted kernel
    run in float64 and the slow reference: positions, and rotation matrices of the kernel's global
    quaternions."""
    from convsynth_jax.kinematics import forward_kinematics_np, global_transforms_np
    from convsynth_jax.rotations import quat_to_matrix_np

    m = random_motion(np.random.default_rng(3), frames=9, joints=7)
    pos, mats = global_transforms_np(m)
    assert pos.dtype == np.float64 and mats.shape == (9, 7, 3, 3)
    np.testing.assert_array_equal(forward_kinematics_np(m), pos)
    np.testing.assert_allclose(pos, fk_reference(m), atol=FK_FLOAT64)
    with enable_x64():
        kpos, kq = fk_kernel(jnp.asarray(m.rotations, jnp.float64), jnp.asarray(m.translations, jnp.float64),
                             m.skeleton.parents)
        np.testing.assert_allclose(pos, np.asarray(kpos), atol=FK_FLOAT64)
        np.testing.assert_allclose(mats, quat_to_matrix_np(np.asarray(kq)), atol=1e-9)


def test_jerk_is_the_third_forward_difference():
    from convsynth_jax.evaluation.metrics import mean_jerk
    from convsynth_jax.kinematics import forward_difference, jerk

    x = np.random.default_rng(0).normal(size=(12, 4, 3))
    j = jerk(x, 30.0)
    slow = np.array([[(x[i + 3, k] - 3 * x[i + 2, k] + 3 * x[i + 1, k] - x[i, k]) * 30.0 ** 3 for k in range(4)]
                     for i in range(9)])
    np.testing.assert_allclose(j, slow, rtol=1e-10, atol=1e-6)
    np.testing.assert_array_equal(j, forward_difference(x, 30.0, 3))
    assert mean_jerk(x, 30.0) == float(np.linalg.norm(j, axis=-1).mean())


def test_joints_below_a_set_of_joints():
    """Skeleton.below: every descendant of the given joints (the renderer and the viewer drop fingers
    with it), none of the given joints themselves, nothing beside them."""
    # 0 root -> 1 spine -> 2 left hand -> 3, 4 fingers (4 below 3); 1 -> 5 right hand -> 6 finger; 0 -> 7 leg
    parents = (-1, 0, 1, 2, 3, 1, 5, 0)
    sk = Skeleton(tuple(f"j{i}" for i in range(8)), parents, np.zeros((8, 3)), tuple(("Zrotation",) for _ in range(8)))
    assert sk.below([2, 5]) == {3, 4, 6}
    assert sk.below([0]) == set(range(1, 8)) and sk.below([]) == set() and sk.below([7]) == set()


def _slow_seam_acceleration(p, fps):
    """Frame by frame, joint by joint: || (p[n+1] - r[n+1]) - 2 (p[n] - r[n]) + (p[n-1] - r[n-1]) || fps^2,
    the ends copied from their neighbours."""
    F, J = p.shape[:2]
    out = np.zeros((F, J))
    if F < 3:
        return out
    for n in range(1, F - 1):
        for j in range(J):
            d = [p[n + k, j] - p[n + k, 0] for k in (-1, 0, 1)]
            out[n, j] = np.linalg.norm((d[2] - 2 * d[1] + d[0]) * fps * fps)
    out[0], out[-1] = out[1], out[-2]
    return out


@pytest.mark.parametrize("frames", [1, 2, 3, 17])
def test_seam_acceleration_equals_the_loops_and_ignores_the_root_path(frames):
    from convsynth_jax.kinematics import seam_acceleration

    rng = np.random.default_rng(frames)
    p = rng.normal(size=(frames, 5, 3))
    np.testing.assert_allclose(seam_acceleration(p, 30.0), _slow_seam_acceleration(p, 30.0), rtol=1e-12)
    moved = p + np.cumsum(rng.normal(size=(frames, 1, 3)), axis=0) ** 2       # any root path, every joint with it
    np.testing.assert_allclose(seam_acceleration(moved, 30.0), seam_acceleration(p, 30.0), atol=1e-9)
