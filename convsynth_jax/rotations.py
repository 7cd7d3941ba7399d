"""Rotation conversions in JAX.

Glossary of conventions used everywhere in convsynth_jax
--------------------------------------------------------
* Quaternions are ``(w, x, y, z)``, scalar first, unit length, Hamilton product.
  ``q`` and ``-q`` are the same rotation; functions never assume a sign unless stated.
* Rotation matrices act on column vectors: ``v' = R @ v``.
* Euler angles follow BVH: an ``order`` string such as ``"ZXY"`` lists the channels in the order
  they appear in the file, and the rotation is ``R = R_Z(a0) @ R_X(a1) @ R_Y(a2)`` (intrinsic
  rotations, first channel outermost). Angles are in radians here; BVH degrees are converted in
  :mod:`convsynth_jax.io.bvh`.
* The world is Y-up and right-handed, as in BVH and the paper.

All functions broadcast over leading axes (``(..., 4)`` quaternions, ``(..., 3, 3)`` matrices), so
they are unbatched primitives that also work on batches without ``vmap``.
"""
from __future__ import annotations

import jax.numpy as jnp

_AXIS_INDEX = {"X": 0, "Y": 1, "Z": 2}


def quat_normalize(q):
    """q: (..., 4) -> unit quaternion (..., 4)."""
    return q / jnp.linalg.norm(q, axis=-1, keepdims=True)


def quat_conjugate(q):
    """Inverse of a unit quaternion."""
    return q * jnp.array([1.0, -1.0, -1.0, -1.0], dtype=q.dtype)


def quat_multiply(a, b):
    """Hamilton product a * b (apply b first, then a). a, b: (..., 4)."""
    aw, ax, ay, az = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bw, bx, by, bz = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    return jnp.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        axis=-1,
    )


def quat_rotate(q, v):
    """Rotate vectors v (..., 3) by unit quaternions q (..., 4)."""
    w = q[..., :1]
    u = q[..., 1:]
    t = 2.0 * jnp.cross(u, v)
    return v + w * t + jnp.cross(u, t)


def quat_to_matrix(q):
    """(..., 4) unit quaternion -> (..., 3, 3) rotation matrix."""
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    r00 = 1 - 2 * (y * y + z * z)
    r01 = 2 * (x * y - w * z)
    r02 = 2 * (x * z + w * y)
    r10 = 2 * (x * y + w * z)
    r11 = 1 - 2 * (x * x + z * z)
    r12 = 2 * (y * z - w * x)
    r20 = 2 * (x * z - w * y)
    r21 = 2 * (y * z + w * x)
    r22 = 1 - 2 * (x * x + y * y)
    return jnp.stack(
        [jnp.stack([r00, r01, r02], -1), jnp.stack([r10, r11, r12], -1), jnp.stack([r20, r21, r22], -1)],
        axis=-2,
    )


def matrix_to_quat(m):
    """(..., 3, 3) rotation matrix -> (..., 4) unit quaternion with w >= 0.

    Uses the numerically stable branch on the largest of (w, x, y, z) (Shepperd's method).
    """
    m00, m11, m22 = m[..., 0, 0], m[..., 1, 1], m[..., 2, 2]
    trace = m00 + m11 + m22
    cand = jnp.stack(
        [
            jnp.stack([1 + trace, m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1]], -1),
            jnp.stack([m[..., 2, 1] - m[..., 1, 2], 1 + m00 - m11 - m22, m[..., 0, 1] + m[..., 1, 0], m[..., 0, 2] + m[..., 2, 0]], -1),
            jnp.stack([m[..., 0, 2] - m[..., 2, 0], m[..., 0, 1] + m[..., 1, 0], 1 - m00 + m11 - m22, m[..., 1, 2] + m[..., 2, 1]], -1),
            jnp.stack([m[..., 1, 0] - m[..., 0, 1], m[..., 0, 2] + m[..., 2, 0], m[..., 1, 2] + m[..., 2, 1], 1 - m00 - m11 + m22], -1),
        ],
        axis=-2,
    )  # (..., 4 candidates, 4)
    diag = jnp.stack([1 + trace, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22, 1 - m00 - m11 + m22], -1)
    best = jnp.argmax(diag, axis=-1)
    q = jnp.take_along_axis(cand, best[..., None, None], axis=-2)[..., 0, :]
    q = quat_normalize(q)
    return jnp.where(q[..., :1] < 0, -q, q)


def axis_angle_to_quat(axis, angle):
    """axis: (..., 3) unit vectors, angle: (...) radians -> (..., 4)."""
    half = 0.5 * angle
    return jnp.concatenate([jnp.cos(half)[..., None], jnp.sin(half)[..., None] * axis], axis=-1)


def _basis_quat(axis_letter: str, angle):
    idx = _AXIS_INDEX[axis_letter]
    half = 0.5 * angle
    zeros = jnp.zeros_like(angle)
    comps = [zeros, zeros, zeros]
    comps[idx] = jnp.sin(half)
    return jnp.stack([jnp.cos(half), *comps], axis=-1)


def euler_to_quat(angles, order: str):
    """angles: (..., 3) radians in channel order; order e.g. "ZXY" -> (..., 4).

    R = R_{order[0]}(angles[...,0]) @ R_{order[1]}(angles[...,1]) @ R_{order[2]}(angles[...,2]).
    """
    order = order.upper()
    if len(order) != 3 or any(c not in _AXIS_INDEX for c in order):
        raise ValueError(f"Euler order must be three of X, Y, Z, got {order!r}")
    q = _basis_quat(order[0], angles[..., 0])
    for k in (1, 2):
        q = quat_multiply(q, _basis_quat(order[k], angles[..., k]))
    return q


def quat_slerp(q0, q1, t):
    """Spherical linear interpolation along the shorter arc. q0, q1: (..., 4); t: (...) in [0, 1]."""
    t = jnp.asarray(t)[..., None]
    dot = jnp.sum(q0 * q1, axis=-1, keepdims=True)
    q1 = jnp.where(dot < 0, -q1, q1)
    dot = jnp.abs(dot)
    dot_c = jnp.clip(dot, -1.0, 1.0)
    theta = jnp.arccos(dot_c)
    sin_theta = jnp.sin(theta)
    small = sin_theta < 1e-6
    safe = jnp.where(small, 1.0, sin_theta)
    w0 = jnp.where(small, 1.0 - t, jnp.sin((1.0 - t) * theta) / safe)
    w1 = jnp.where(small, t, jnp.sin(t * theta) / safe)
    return quat_normalize(w0 * q0 + w1 * q1)


def yaw_quat(q, up_axis: int = 1):
    """The rotation about the up axis (the heading) contained in q. q: (..., 4) -> (..., 4).

    Swing-twist decomposition: keep the w and up-axis components and renormalize.
    """
    q = jnp.asarray(q)
    keep = jnp.zeros(4, dtype=q.dtype).at[0].set(1.0).at[1 + up_axis].set(1.0)
    tw = q * keep
    norm = jnp.linalg.norm(tw, axis=-1, keepdims=True)
    identity = jnp.zeros(4, dtype=q.dtype).at[0].set(1.0)
    return jnp.where(norm < 1e-9, identity, tw / jnp.where(norm < 1e-9, 1.0, norm))


# --------------------------------------------------------------------------------------------------
# Host-side (NumPy, float64) versions for file I/O, data generation and realization, which work on
# whole recordings outside jit. Same conventions as above: (w, x, y, z) quaternions, BVH Euler
# orders (intrinsic, first channel outermost), Y up. Euler conversions go through SciPy (whose
# upper-case orders are intrinsic); the (w, x, y, z) <-> SciPy (x, y, z, w) shuffles live here only.
import numpy as np  # noqa: E402
from scipy.spatial.transform import Rotation as _Rotation  # noqa: E402


def _to_scipy(q: np.ndarray) -> np.ndarray:
    return np.asarray(q, dtype=np.float64)[..., [1, 2, 3, 0]]


def _from_scipy(q: np.ndarray) -> np.ndarray:
    return q[..., [3, 0, 1, 2]]


def euler_deg_to_quat_np(angles_deg, order: str) -> np.ndarray:
    """(..., 3) BVH Euler angles in degrees (channel order ``order``) -> (..., 4) quaternions."""
    a = np.asarray(angles_deg, dtype=np.float64)
    q = _Rotation.from_euler(order.upper(), a.reshape(-1, 3), degrees=True).as_quat()
    return _from_scipy(q).reshape(a.shape[:-1] + (4,))


def quat_to_euler_deg_np(q, order: str) -> np.ndarray:
    """(..., 4) quaternions -> (..., 3) BVH Euler angles in degrees for channel order ``order``."""
    q = np.asarray(q, dtype=np.float64)
    e = _Rotation.from_quat(_to_scipy(q).reshape(-1, 4)).as_euler(order.upper(), degrees=True)
    return e.reshape(q.shape[:-1] + (3,))


def quat_to_matrix_np(q) -> np.ndarray:
    """(..., 4) (w, x, y, z) -> (..., 3, 3), float64 NumPy (:func:`quat_to_matrix`'s formula)."""
    w, x, y, z = np.moveaxis(np.asarray(q, dtype=np.float64), -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)], -2)


def matrix_to_quat_np(m) -> np.ndarray:
    """(..., 3, 3) rotation matrices -> (..., 4) (w, x, y, z) quaternions, float64 NumPy (SciPy's
    conversion; :func:`matrix_to_quat` is the jnp kernel's)."""
    m = np.asarray(m, dtype=np.float64)
    q = _Rotation.from_matrix(m.reshape(-1, 3, 3)).as_quat()
    return _from_scipy(q).reshape(m.shape[:-2] + (4,))


def quat_multiply_np(a, b) -> np.ndarray:
    """Hamilton product a * b of (..., 4) quaternions (NumPy, broadcasting)."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack([aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw], axis=-1)


def quat_slerp_np(q0, q1, t) -> np.ndarray:
    """Spherical linear interpolation along the shorter arc (NumPy float64). q0, q1: (..., 4); t: (...)."""
    q0, q1 = np.asarray(q0, dtype=np.float64), np.asarray(q1, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)[..., None]
    dot = np.sum(q0 * q1, axis=-1, keepdims=True)
    q1 = np.where(dot < 0, -q1, q1)
    dot = np.clip(np.abs(dot), 0.0, 1.0)
    theta = np.arccos(dot)
    sin = np.sin(theta)
    small = sin < 1e-6
    w0 = np.where(small, 1.0 - t, np.sin((1.0 - t) * theta) / np.where(small, 1.0, sin))
    w1 = np.where(small, t, np.sin(t * theta) / np.where(small, 1.0, sin))
    q = w0 * q0 + w1 * q1
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def quat_conjugate_np(q) -> np.ndarray:
    """Inverse of (..., 4) unit quaternions (NumPy)."""
    return np.asarray(q, dtype=np.float64) * np.array([1.0, -1.0, -1.0, -1.0])


def yaw_angle_np(q) -> np.ndarray:
    """Heading about +Y (radians) of (..., 4) quaternions: the angle of their swing-twist yaw."""
    q = np.asarray(q, dtype=np.float64)
    return 2.0 * np.arctan2(q[..., 2], q[..., 0])


def yaw_to_quat_np(angle) -> np.ndarray:
    """(...) radians about +Y -> (..., 4) quaternions."""
    a = 0.5 * np.asarray(angle, dtype=np.float64)
    z = np.zeros_like(a)
    return np.stack([np.cos(a), z, np.sin(a), z], axis=-1)


def joint_turn_deg_np(q) -> np.ndarray:
    """(n - 1,) the largest turn (degrees) of any joint below the root from frame g to g + 1, for
    rotations q: (n, J, 4) of one clip (a marker-swap glitch turns a joint 16-180 degrees in one frame)."""
    q = np.asarray(q, np.float64)[:, 1:]
    dots = np.clip(np.abs(np.sum(q[1:] * q[:-1], axis=-1)), 0.0, 1.0)
    return np.rad2deg(2.0 * np.arccos(dots)).max(axis=-1, initial=0.0)


def rotate_about_y_np(v, angle) -> np.ndarray:
    """Rotate (..., 3) vectors by (...) radians about +Y (right-handed)."""
    v = np.asarray(v, dtype=np.float64)
    c, s = np.cos(angle), np.sin(angle)
    return np.stack([c * v[..., 0] + s * v[..., 2], v[..., 1], -s * v[..., 0] + c * v[..., 2]], axis=-1)


def quat_to_euler(q, order: str):
    """(..., 4) unit quaternions -> (..., 3) Euler angles in radians, inverse of :func:`euler_to_quat`.

    For R = R_i(a) R_j(b) R_k(c) with (i, j, k) = order and s = +1 for cyclic orders (XYZ, YZX,
    ZXY), -1 otherwise: b = asin(s R[i,k]), a = atan2(-s R[j,k], R[k,k]), c = atan2(-s R[i,j], R[i,i]).
    The middle angle lies in [-pi/2, pi/2]; the outer two in (-pi, pi].
    """
    order = order.upper()
    if len(order) != 3 or sorted(order) != ["X", "Y", "Z"]:
        raise ValueError(f"Euler order must be a permutation of XYZ, got {order!r}")
    i, j, k = (_AXIS_INDEX[c] for c in order)
    s = 1.0 if (i, j, k) in ((0, 1, 2), (1, 2, 0), (2, 0, 1)) else -1.0
    m = quat_to_matrix(q)
    b = jnp.arcsin(jnp.clip(s * m[..., i, k], -1.0, 1.0))
    a = jnp.arctan2(-s * m[..., j, k], m[..., k, k])
    c = jnp.arctan2(-s * m[..., i, j], m[..., i, i])
    return jnp.stack([a, b, c], axis=-1)
