"""Forward kinematics and the root-relative pose features of the paper's transition cost.

Shapes: F frames, J joints. Kernels are jitted with the skeleton topology (parents) static, the
frame axis is vectorized, and the joint loop is unrolled at trace time (J is small).
"""
from __future__ import annotations

from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .rotations import quat_conjugate, quat_multiply, quat_rotate, quat_to_matrix, yaw_quat
from .skeleton import Motion


@partial(jax.jit, static_argnames=("parents",))
def fk_kernel(rotations, translations, parents: tuple[int, ...]):
    """Global joint transforms.

    rotations: (F, J, 4) local quaternions; translations: (F, J, 3) local translations;
    parents: static tuple, parent precedes child. Returns (positions (F, J, 3), rotations (F, J, 4)).
    """
    mats = quat_to_matrix(rotations)  # (F, J, 3, 3)
    g_mats = [None] * len(parents)
    g_pos = [None] * len(parents)
    for j, p in enumerate(parents):
        if p < 0:
            g_mats[j] = mats[:, j]
            g_pos[j] = translations[:, j]
        else:
            g_mats[j] = g_mats[p] @ mats[:, j]
            g_pos[j] = g_pos[p] + jnp.einsum("fab,fb->fa", g_mats[p], translations[:, j])
    positions = jnp.stack(g_pos, axis=1)
    # Global quaternions via the product chain (exact, no matrix->quat round trip).
    g_q = [None] * len(parents)
    for j, p in enumerate(parents):
        g_q[j] = rotations[:, j] if p < 0 else quat_multiply(g_q[p], rotations[:, j])
    return positions, jnp.stack(g_q, axis=1)


def forward_kinematics(motion: Motion, dtype=jnp.float32) -> jax.Array:
    """Global joint positions (F, J, 3) in the file's units."""
    pos, _ = global_transforms(motion, dtype=dtype)
    return pos


def global_transforms(motion: Motion, dtype=jnp.float32):
    """Global joint positions (F, J, 3) and rotations (F, J, 4) of every frame."""
    rot = jnp.asarray(motion.rotations, dtype=dtype)
    trans = jnp.asarray(motion.translations, dtype=dtype)
    return fk_kernel(rot, trans, tuple(motion.skeleton.parents))


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


def joint_weights(motion_or_skeleton, finger_pattern=None, overrides=None) -> np.ndarray:
    """Eq. 4 joint weights w_b: 1 by default, 0 for finger joints (detected by name)."""
    from .skeleton import DEFAULT_FINGER_PATTERN, Skeleton

    skel = motion_or_skeleton if isinstance(motion_or_skeleton, Skeleton) else motion_or_skeleton.skeleton
    return skel.joint_weights(DEFAULT_FINGER_PATTERN if finger_pattern is None else finger_pattern, overrides)
