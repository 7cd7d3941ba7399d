"""Forward kinematics, the root-relative pose features of the paper's transition cost, and time
derivatives of positions (velocities, jerk): the project's one home for each.

Shapes: F frames, J joints. The forward-kinematics recursion has two forms: the jitted kernel
(:func:`fk_kernel`, float32 by default, one FK call for many clips in :func:`padded_global_transforms`),
which scans over the joints, and the float64 NumPy path (:func:`global_transforms_np`, no compilation
per clip length), which loops over them (:func:`_chain`). Kernels are jitted with the skeleton topology
(parents) static and the frame axis vectorized.
"""
from __future__ import annotations

from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .rotations import quat_conjugate, quat_multiply, quat_rotate, quat_to_matrix, quat_to_matrix_np, yaw_quat
from .skeleton import Motion


def _chain(mats, translations, parents: tuple[int, ...]):
    """The forward-kinematics recursion in NumPy, parent before child: global rotation matrices
    g_j = g_parent(j) @ R_j and positions p_j = p_parent(j) + g_parent(j) t_j, as two lists of J
    arrays ((F, 3, 3) and (F, 3)). mats: (F, J, 3, 3) local rotation matrices; translations:
    (F, J, 3)."""
    g_mats = [None] * len(parents)
    g_pos = [None] * len(parents)
    for j, p in enumerate(parents):
        if p < 0:
            g_mats[j] = mats[:, j]
            g_pos[j] = translations[:, j]
        else:
            g_mats[j] = g_mats[p] @ mats[:, j]
            g_pos[j] = g_pos[p] + np.einsum("fab,fb->fa", g_mats[p], translations[:, j])
    return g_mats, g_pos


@partial(jax.jit, static_argnames=("parents",))
def fk_kernel(rotations, translations, parents: tuple[int, ...]):
    """Global joint transforms.

    rotations: (F, J, 4) local quaternions; translations: (F, J, 3) local translations;
    parents: static tuple, parent precedes child. Returns (positions (F, J, 3), rotations (F, J, 4)).

    The recursion of :func:`_chain` as a ``lax.scan`` over the joints (one compiled step, not J
    unrolled ones: compiling the unrolled chain took seconds even for a 22-joint rig). A root joint
    takes its local transform as it is; global rotations are the product chain of the local
    quaternions (exact, no matrix->quaternion round trip).
    """
    J = len(parents)
    mats = jnp.moveaxis(quat_to_matrix(rotations), 1, 0)     # (J, F, 3, 3): a joint's frames contiguous
    tr = jnp.moveaxis(translations, 1, 0)                     # (J, F, 3)
    q = jnp.moveaxis(rotations, 1, 0)                         # (J, F, 4)
    joint = jnp.arange(J, dtype=jnp.int32)
    parent = jnp.asarray([max(p, 0) for p in parents], jnp.int32)
    root = jnp.asarray([p < 0 for p in parents])

    def step(carry, x):
        g_mats, g_pos, g_q = carry
        j, p, is_root = x
        pm = g_mats[p]
        g_mats = g_mats.at[j].set(jnp.where(is_root, mats[j], pm @ mats[j]))
        g_pos = g_pos.at[j].set(jnp.where(is_root, tr[j], g_pos[p] + jnp.einsum("fab,fb->fa", pm, tr[j])))
        g_q = g_q.at[j].set(jnp.where(is_root, q[j], quat_multiply(g_q[p], q[j])))
        return (g_mats, g_pos, g_q), None

    (_, g_pos, g_q), _ = jax.lax.scan(step, (mats, tr, q), (joint, parent, root))
    return jnp.moveaxis(g_pos, 0, 1), jnp.moveaxis(g_q, 0, 1)


def forward_kinematics(motion: Motion, dtype=jnp.float32) -> jax.Array:
    """Global joint positions (F, J, 3) in the file's units."""
    pos, _ = global_transforms(motion, dtype=dtype)
    return pos


def global_transforms(motion: Motion, dtype=jnp.float32):
    """Global joint positions (F, J, 3) and rotations (F, J, 4) of every frame."""
    rot = jnp.asarray(motion.rotations, dtype=dtype)
    trans = jnp.asarray(motion.translations, dtype=dtype)
    return fk_kernel(rot, trans, tuple(motion.skeleton.parents))


def global_transforms_np(motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    """Global joint positions (F, J, 3) and rotation matrices (F, J, 3, 3), float64 NumPy.

    The same recursion as :func:`fk_kernel`, unjitted: the jitted kernel compiles once per clip
    length (seconds on a small CPU), so code that touches hundreds of clip lengths (Walk the Talk's
    splicing and evaluation) takes this path; a test checks it against the kernel.
    """
    mats = quat_to_matrix_np(motion.rotations)
    tr = np.asarray(motion.translations, dtype=np.float64)
    g_mats, g_pos = _chain(mats, tr, tuple(motion.skeleton.parents))
    return np.stack(g_pos, axis=1), np.stack(g_mats, axis=1)


def forward_kinematics_np(motion: Motion) -> np.ndarray:
    """Global joint positions (F, J, 3), float64 NumPy (see :func:`global_transforms_np`)."""
    mats = quat_to_matrix_np(motion.rotations)
    tr = np.asarray(motion.translations, dtype=np.float64)
    return np.stack(_chain(mats, tr, tuple(motion.skeleton.parents))[1], axis=1)


def padded_global_transforms(motions):
    """Global joint positions and rotations of many clips of one skeleton with one forward-kinematics
    call, through its stored executable (kernel_cache.py: a second run skips tracing the joint chain).
    The frames, concatenated, are padded with copies of the last one to a power of two so the kernel
    compiles for few shapes. Returns (positions (P, J, 3), rotations (P, J, 4)) device float32 arrays
    and the real frame count n <= P."""
    from . import kernel_cache

    n = sum(m.rotations.shape[0] for m in motions)
    size = 1 << max(0, int(np.ceil(np.log2(max(n, 1)))))
    # one padded float32 buffer each, filled clip by clip (the same values as concatenating, casting
    # and padding with copies of the last frame, without the intermediate copies)
    rot = np.empty((size,) + motions[0].rotations.shape[1:], np.float32)
    tr = np.empty((size,) + motions[0].translations.shape[1:], np.float32)
    start = 0
    for m in motions:
        stop = start + m.rotations.shape[0]
        rot[start:stop] = m.rotations
        tr[start:stop] = m.translations
        start = stop
    if 0 < n < size:
        rot[n:] = rot[n - 1]
        tr[n:] = tr[n - 1]
    pos, grot = kernel_cache.call(fk_kernel, "fk", (jax.device_put(rot), jax.device_put(tr)),
                                  {"parents": tuple(motions[0].skeleton.parents)})
    return pos, grot, n


@partial(jax.jit, static_argnames=("up_axis", "remove_yaw"))
def root_relative_kernel(positions, global_rotations, up_axis: int = 1, remove_yaw: bool = True):
    """Joint positions relative to the root: subtract the root position and, if ``remove_yaw``,
    undo the root's heading (rotation about the up axis), so the features do not depend on where
    the character stands or which way it faces. positions: (F, J, 3) -> (F, J, 3)."""
    rel = positions - positions[:, :1]
    if remove_yaw:
        heading = yaw_quat(global_rotations[:, 0], up_axis)  # (F, 4)
        inv = quat_conjugate(heading)[:, None, :]
        rel = quat_rotate(jnp.broadcast_to(inv, rel.shape[:-1] + (4,)), rel)
    return rel


def finite_difference(x, fps: float):
    """Per-second derivative along axis 0: central differences inside, one-sided at the ends.
    x: (F, ...) -> (F, ...). A single frame has zero velocity."""
    x = jnp.asarray(x)
    if x.shape[0] < 2:
        return jnp.zeros_like(x)
    d = jnp.concatenate([x[1:2] - x[0:1], 0.5 * (x[2:] - x[:-2]), x[-1:] - x[-2:-1]], axis=0)
    return d * fps


def forward_difference(x, fps: float, order: int = 1) -> np.ndarray:
    """order-th forward-difference derivative along axis 0, float64 NumPy, in units per
    second**order: (F, ...) -> (F - order, ...). Row i spans frames i..i+order."""
    x = np.asarray(x, dtype=np.float64)
    for _ in range(order):
        x = np.diff(x, axis=0) * fps
    return x


def seam_acceleration(positions, fps: float) -> np.ndarray:
    """(F, J) joint acceleration magnitudes relative to the root joint, float64, units per second**2:
    the central second difference of ``positions - positions[:, :1]``; the first and last frames take
    their neighbour's values, a clip of fewer than 3 frames is all zeros. The project's one definition
    of how sharp a frame is, read at seams: by the seam filter of the motion graph (graph/seams.py, on
    the database's positions, which are root-relative in the root's heading frame) and by the seam
    metrics of the evaluation (evaluation/metrics.py, on forward kinematics as played, whose heading is
    not undone). The heading is the caller's choice of ``positions``, not a second formula."""
    p = np.asarray(positions, dtype=np.float64)
    if p.shape[0] < 3:
        return np.zeros(p.shape[:2])
    a = np.linalg.norm(forward_difference(p - p[:, :1], fps, 2), axis=-1)
    return np.concatenate([a[:1], a, a[-1:]])


def jerk(positions, fps: float) -> np.ndarray:
    """Jerk, the third time derivative of positions: (F, ...) -> (F - 3, ...) float64, units per
    second**3; row i spans frames i..i+3. The project's one definition (motion-quality metrics,
    Walk the Talk's wrist jerk)."""
    return forward_difference(positions, fps, 3)


class PoseFeatures(NamedTuple):
    """Root-relative pose features of every frame (Eq. 3-4 inputs).

    positions: (F, J, 3) root-relative joint positions; velocities: (F, J, 3) their time
    derivatives in units per second; global_positions: (F, J, 3) world positions.
    """

    positions: jax.Array
    velocities: jax.Array
    global_positions: jax.Array


def pose_features(motion: Motion, up_axis: int = 1, remove_yaw: bool = True, dtype=jnp.float32) -> PoseFeatures:
    """Root-relative positions and velocities (fps-aware finite differences) of a motion."""
    pos, rot = global_transforms(motion, dtype=dtype)
    rel = root_relative_kernel(pos, rot, up_axis=up_axis, remove_yaw=remove_yaw)
    vel = finite_difference(rel, motion.fps)
    return PoseFeatures(rel, vel, pos)


def batched_pose_features(motions, up_axis: int = 1, remove_yaw: bool = True):
    """Root-relative positions and velocities of many clips of one skeleton with one FK call
    (:func:`padded_global_transforms`). Velocities are differenced within each clip. Returns float32
    (N, J, 3) arrays."""
    from . import kernel_cache

    pos, grot, n = padded_global_transforms(motions)
    rel = np.asarray(kernel_cache.call(root_relative_kernel, "root_relative", (pos, grot),
                                       {"up_axis": up_axis, "remove_yaw": remove_yaw}))[:n]
    vel = np.empty_like(rel)
    start = 0
    for m in motions:
        stop = start + m.num_frames
        x = rel[start:stop]
        if len(x) < 2:
            vel[start:stop] = 0
        else:
            vel[start:stop] = np.gradient(x, axis=0) * m.fps
        start = stop
    return rel.astype(np.float32), vel.astype(np.float32)


def joint_weights(motion_or_skeleton, finger_pattern=None, overrides=None) -> np.ndarray:
    """Eq. 4 joint weights w_b: 1 by default, 0 for finger joints (detected by name)."""
    from .rig import FINGER_PATTERN
    from .skeleton import Skeleton

    skel = motion_or_skeleton if isinstance(motion_or_skeleton, Skeleton) else motion_or_skeleton.skeleton
    return skel.joint_weights(FINGER_PATTERN if finger_pattern is None else finger_pattern, overrides)
