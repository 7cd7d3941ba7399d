"""The hand stream of the CDBN (Sec. IV-C, VIII: "arms (3 DOF x 2) and forearms (2 DOF x 2)"):
10-D arm features per frame, their inverse, key-point smoothing (12 key points per second, Sec. VI-B)
and the write-back into a full-body Motion.

Our reconstruction (the paper names the degrees of freedom, not their parametrization):
* upper arm (3 DOF): the rotation vector (axis * angle, degrees) of the joint's local rotation;
* forearm (2 DOF): the swing part of the local rotation (swing-twist decomposition about the bone
  axis, the direction of the hand joint's rest offset), as a rotation vector perpendicular to that
  axis, written in a fixed basis (u, v) of the perpendicular plane. The twist (pronation) about the
  bone is the dropped degree of freedom; it does not move the wrist. On synthesis the twist is
  identity.
Order of the 10 columns: left arm (3), left forearm (2), right arm (3), right forearm (2).
Joints come from ``CDBNFeatureParams.arm_joints``: four entries, each a role of
:data:`convsynth_jax.rig.RIG_JOINTS` (the default: both upper arms and forearms, on every rig the
table knows) or a ``|``-separated list of alternative exact joint names.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from ..errors import CDBNError
from ..rig import resolve_joint

HAND_NAMES = ("l_arm_x", "l_arm_y", "l_arm_z", "l_forearm_u", "l_forearm_v",
              "r_arm_x", "r_arm_y", "r_arm_z", "r_forearm_u", "r_forearm_v")


class ArmRig(NamedTuple):
    """Joint indices (left arm, left forearm, right arm, right forearm) and, per forearm, the unit bone
    axis and the (u, v) basis of its perpendicular plane (forearm-local coordinates)."""

    joints: tuple
    axes: np.ndarray     # (2, 3)
    bases: np.ndarray    # (2, 2, 3)


def _perp_basis(a: np.ndarray) -> np.ndarray:
    helper = np.eye(3)[int(np.argmin(np.abs(a)))]
    u = np.cross(a, helper)
    u /= np.linalg.norm(u)
    return np.stack([u, np.cross(a, u)])


def arm_rig(skeleton, params) -> ArmRig:
    """Resolve ``params.arm_joints`` on ``skeleton``; CDBNError listing the joints when one is missing."""
    spec = tuple(params.arm_joints)
    if len(spec) != 4:
        raise CDBNError(f"cdbn.features.arm_joints needs 4 entries (left arm, left forearm, right arm, right "
                        f"forearm), got {list(spec)}")
    idx = []
    for entry in spec:
        j = resolve_joint(skeleton, entry)
        if j is None:
            raise CDBNError(f"skeleton has no joint named any of {str(entry).split('|')} nor playing that role "
                            f"(cdbn.features.arm_joints: roles of convsynth_jax.rig or joint names); joints are "
                            f"{list(skeleton.names)}")
        idx.append(j)
    axes, bases = [], []
    for fj in (idx[1], idx[3]):
        kids = skeleton.children(fj)
        off = np.asarray(skeleton.offsets[kids[0]], np.float64) if kids else np.zeros(3)
        if np.linalg.norm(off) < 1e-9:
            ends = [np.asarray(o, np.float64) for p, o in skeleton.end_sites if p == fj]
            off = ends[0] if ends else np.array([1.0, 0.0, 0.0])
        a = off / np.linalg.norm(off)
        axes.append(a)
        bases.append(_perp_basis(a))
    return ArmRig(tuple(idx), np.stack(axes), np.stack(bases))


def _rotations(motion, j: int) -> Rotation:
    return Rotation.from_quat(np.asarray(motion.rotations[:, j], np.float64)[:, [1, 2, 3, 0]])


def swing_of(r: Rotation, axis: np.ndarray) -> Rotation:
    """The swing part of r = swing * twist, twist about ``axis`` (unit, local frame)."""
    q = r.as_quat()                      # x, y, z, w
    proj = (q[:, :3] @ axis)[:, None] * axis[None]
    tw = np.concatenate([proj, q[:, 3:]], axis=1)
    n = np.linalg.norm(tw, axis=1, keepdims=True)
    tw = np.where(n > 1e-12, tw / np.maximum(n, 1e-12), np.array([0.0, 0.0, 0.0, 1.0]))
    return r * Rotation.from_quat(tw).inv()


def arm_angles(motion, params, rig: ArmRig | None = None) -> np.ndarray:
    """(F, 10) degrees: the hand-stream features of a Motion (see the module docstring)."""
    rig = rig or arm_rig(motion.skeleton, params)
    cols = []
    for side in range(2):
        arm, fore = rig.joints[2 * side], rig.joints[2 * side + 1]
        cols.append(np.degrees(_rotations(motion, arm).as_rotvec()))
        sw = np.degrees(swing_of(_rotations(motion, fore), rig.axes[side]).as_rotvec())
        cols.append(sw @ rig.bases[side].T)
    return np.concatenate(cols, axis=1)


def arm_quaternions(angles: np.ndarray, rig: ArmRig) -> np.ndarray:
    """(F, 10) features -> (F, 4, 4) local quaternions (w, x, y, z) of the four joints (forearm twist
    identity)."""
    a = np.asarray(angles, np.float64)
    out = []
    for side in range(2):
        b = 5 * side
        out.append(Rotation.from_rotvec(np.radians(a[:, b:b + 3])).as_quat())
        rv = np.radians(a[:, b + 3:b + 5]) @ rig.bases[side]
        out.append(Rotation.from_rotvec(rv).as_quat())
    return np.stack(out, axis=1)[..., [3, 0, 1, 2]]


def keypoint_smooth_joints(quats: np.ndarray, fps: float, keypoints_per_second: float) -> np.ndarray:
    """Key-point smoothing per joint: quaternions (T, J, 4) (w, x, y, z) kept at equidistant key points
    (every fps / rate frames, and the last frame), slerp between them (Sec. VI-B)."""
    q = np.asarray(quats, np.float64)
    T = len(q)
    if T < 3 or keypoints_per_second <= 0:
        return q
    step = max(fps / keypoints_per_second, 1.0)
    keys = np.unique(np.concatenate([np.round(np.arange(0, T - 1, step)).astype(int), [T - 1]]))
    out = np.empty_like(q)
    for j in range(q.shape[1]):
        s = Slerp(keys.astype(np.float64), Rotation.from_quat(q[keys, j][:, [1, 2, 3, 0]]))
        out[:, j] = s(np.arange(T, dtype=np.float64)).as_quat()[:, [3, 0, 1, 2]]
    return out


def smooth_arm_angles(angles: np.ndarray, rig: ArmRig, fps: float, keypoints_per_second: float) -> np.ndarray:
    """Key-point smoothing in joint-rotation space, back to the 10 features."""
    q = keypoint_smooth_joints(arm_quaternions(angles, rig), fps, keypoints_per_second)
    cols = []
    for side in range(2):
        cols.append(np.degrees(Rotation.from_quat(q[:, 2 * side][:, [1, 2, 3, 0]]).as_rotvec()))
        rv = np.degrees(Rotation.from_quat(q[:, 2 * side + 1][:, [1, 2, 3, 0]]).as_rotvec())
        cols.append(rv @ rig.bases[side].T)
    return np.concatenate(cols, axis=1)


def arms_into_motion(template, quats: np.ndarray, rig: ArmRig, name: str = ""):
    """A full-skeleton Motion of len(quats) frames: every joint at the template's mean rotation and first
    frame's translations, the four arm joints from ``quats`` (F, 4, 4)."""
    from ..skeleton import Motion

    skel = template.skeleton
    F = len(quats)
    rot = np.asarray(template.rotations, np.float64)
    mean_rot = np.stack([Rotation.from_quat(rot[:, j][:, [1, 2, 3, 0]]).mean().as_quat()[[3, 0, 1, 2]]
                         for j in range(skel.num_joints)])
    rots = np.broadcast_to(mean_rot, (F, skel.num_joints, 4)).copy()
    for k, j in enumerate(rig.joints):
        rots[:, j] = quats[:, k]
    trans = np.broadcast_to(np.asarray(template.translations[0]), (F,) + template.translations.shape[1:]).copy()
    return Motion(skel, rots, trans, float(template.fps), name or template.name)
