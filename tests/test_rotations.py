import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from convsynth_jax import rotations as R
from tolerances import ROTATION

ORDERS = ["XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX", "XYX", "ZXZ"]
angles = st.lists(st.floats(-3.1, 3.1), min_size=3, max_size=3)
quats = st.lists(st.floats(-1, 1), min_size=4, max_size=4).filter(lambda q: np.linalg.norm(q) > 0.1)


def _same_rotation(q_wxyz, rot: Rotation):
    ref = rot.as_quat()[[3, 0, 1, 2]]
    q = np.asarray(q_wxyz, np.float64)
    return min(np.abs(q - ref).max(), np.abs(q + ref).max())


@pytest.mark.parametrize("order", ORDERS)
@settings(max_examples=8, deadline=None)
@given(a=angles)
def test_euler_to_quat_matches_scipy_intrinsic(order, a):
    q = R.euler_to_quat(np.asarray(a, np.float32), order)
    assert _same_rotation(q, Rotation.from_euler(order, a)) < ROTATION * 10


@settings(max_examples=25, deadline=None)
@given(q=quats)
def test_matrix_round_trip_and_scipy(q):
    q = np.asarray(q, np.float64) / np.linalg.norm(q)
    m = np.asarray(R.quat_to_matrix(q))
    np.testing.assert_allclose(m, Rotation.from_quat(q[[1, 2, 3, 0]]).as_matrix(), atol=ROTATION)
    q2 = np.asarray(R.matrix_to_quat(m))
    assert _same_rotation(q2, Rotation.from_quat(q[[1, 2, 3, 0]])) < ROTATION * 10


@settings(max_examples=25, deadline=None)
@given(a=quats, b=quats, v=st.lists(st.floats(-10, 10), min_size=3, max_size=3))
def test_multiply_and_rotate_match_scipy(a, b, v):
    a = np.asarray(a) / np.linalg.norm(a)
    b = np.asarray(b) / np.linalg.norm(b)
    ra, rb = Rotation.from_quat(a[[1, 2, 3, 0]]), Rotation.from_quat(b[[1, 2, 3, 0]])
    assert _same_rotation(R.quat_multiply(a, b), ra * rb) < ROTATION * 10
    np.testing.assert_allclose(R.quat_rotate(a, np.asarray(v)), ra.apply(v), atol=1e-4)


def test_slerp_endpoints_midpoint_and_shortest_arc():
    q0 = np.array([1.0, 0, 0, 0])
    q1 = Rotation.from_euler("Y", 90, degrees=True).as_quat()[[3, 0, 1, 2]]
    np.testing.assert_allclose(R.quat_slerp(q0, q1, 0.0), q0, atol=1e-6)
    np.testing.assert_allclose(R.quat_slerp(q0, q1, 1.0), q1, atol=1e-6)
    mid = np.asarray(R.quat_slerp(q0, q1, 0.5))
    assert _same_rotation(mid, Rotation.from_euler("Y", 45, degrees=True)) < 1e-6
    # -q1 is the same rotation: slerp must take the short way and give the same midpoint
    assert _same_rotation(R.quat_slerp(q0, -q1, 0.5), Rotation.from_euler("Y", 45, degrees=True)) < 1e-6


def test_yaw_extracts_heading():
    r = Rotation.from_euler("YXZ", [40, 10, -5], degrees=True)
    yaw = np.asarray(R.yaw_quat(r.as_quat()[[3, 0, 1, 2]]))
    assert np.isclose(np.degrees(2 * np.arctan2(yaw[2], yaw[0])), 40, atol=1.5)
    assert abs(yaw[1]) < 1e-7 and abs(yaw[3]) < 1e-7


def test_bad_order_rejected():
    with pytest.raises(ValueError):
        R.euler_to_quat(np.zeros(3), "XQZ")


# ------------------------------------------------------------------ host-side (NumPy) helpers
def test_numpy_helpers_agree_with_the_jax_primitives():
    rng = np.random.default_rng(3)
    ang = rng.uniform(-170, 170, (50, 3))
    for order in ("ZXY", "XYZ", "YXZ", "ZYX"):
        q = R.euler_deg_to_quat_np(ang, order)
        ref = np.asarray(R.euler_to_quat(np.deg2rad(ang), order), dtype=np.float64)
        np.testing.assert_allclose(np.abs(np.sum(q * ref, -1)), 1.0, atol=1e-6)  # same rotation (sign-free)
        back = R.euler_deg_to_quat_np(R.quat_to_euler_deg_np(q, order), order)
        np.testing.assert_allclose(np.abs(np.sum(q * back, -1)), 1.0, atol=1e-9)
    a, b = R.euler_deg_to_quat_np(ang, "ZXY"), R.euler_deg_to_quat_np(ang[::-1], "XYZ")
    np.testing.assert_allclose(R.quat_multiply_np(a, b), np.asarray(R.quat_multiply(a, b)), atol=1e-6)
    yaw = rng.uniform(-3, 3, 50)
    q = R.yaw_to_quat_np(yaw)
    np.testing.assert_allclose(R.yaw_angle_np(q), yaw, atol=1e-12)
    v = rng.normal(size=(50, 3))
    np.testing.assert_allclose(R.rotate_about_y_np(v, yaw), np.asarray(R.quat_rotate(q, v)), atol=1e-5)
    # the yaw of a tilted rotation is its swing-twist heading, as yaw_quat computes it
    tilted = R.quat_multiply_np(q, R.euler_deg_to_quat_np(np.c_[np.zeros(50), rng.uniform(-30, 30, 50), np.zeros(50)], "YXZ"))
    np.testing.assert_allclose(R.yaw_to_quat_np(R.yaw_angle_np(tilted)) * np.sign(tilted[:, :1]),
                               np.asarray(R.yaw_quat(tilted)) * np.sign(tilted[:, :1]), atol=1e-6)


def test_matrix_to_quat_np_is_the_kernels_conversion_in_float64():
    """One matrix-to-quaternion conversion per array library (Walk the Talk's gaze and gesture retargeting
    use ``matrix_to_quat_np``): the same rotation as the jnp kernel's, up to the quaternion's sign."""
    from scipy.spatial.transform import Rotation

    from convsynth_jax.rotations import matrix_to_quat, matrix_to_quat_np, quat_to_matrix_np

    m = Rotation.random(50, random_state=1).as_matrix().reshape(5, 10, 3, 3)
    q = matrix_to_quat_np(m)
    assert q.shape == (5, 10, 4) and q.dtype == np.float64
    np.testing.assert_allclose(quat_to_matrix_np(q), m, atol=1e-12)
    k = np.asarray(matrix_to_quat(m.astype(np.float32)), np.float64)
    np.testing.assert_allclose(np.abs(np.sum(q * k, axis=-1)), 1.0, atol=1e-5)
