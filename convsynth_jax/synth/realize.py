"""Realization (paper Section 7.1): poses along a path, root integrated from velocities, blending.

* Joint rotations come from the source frames. At every synthetic transition the following
  ``blend_frames`` output frames are cross-faded from the continuation of the previous source clip
  into the new one with cosine weights, slerping every joint rotation.
* The root's ground-plane velocity and yaw rate are taken from each source frame in its own heading
  frame and integrated from a chair placement (position and heading); its height and its tilt
  (rotation without heading) come from the source frame.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from ..rotations import quat_slerp
from ..skeleton import Motion


def _yaw_angle(q_wxyz: np.ndarray) -> np.ndarray:
    """Heading about +Y of quaternions (…, 4) in radians (swing-twist)."""
    w, y = q_wxyz[..., 0], q_wxyz[..., 2]
    return 2.0 * np.arctan2(y, w)


def _yaw_quat(angle):
    return np.stack([np.cos(angle / 2), np.zeros_like(angle), np.sin(angle / 2), np.zeros_like(angle)], -1)


def _qmul(a, b):
    return Rotation.from_quat(a[..., [1, 2, 3, 0]]) * Rotation.from_quat(b[..., [1, 2, 3, 0]])


def realize(source_clips, source_frames, motions: dict, synthetic_at, chair=(0.0, 0.0, 0.0), chair_yaw_deg=0.0,
            blend_frames: int = 6) -> Motion:
    """source_clips/source_frames: (T,) clip name and frame per output frame; motions: clip name ->
    Motion; synthetic_at: output frames t whose transition (t-1 -> t) is synthetic."""
    T = len(source_frames)
    m0 = motions[source_clips[0]]
    skel, fps = m0.skeleton, m0.fps
    rot = np.stack([motions[c].rotations[f] for c, f in zip(source_clips, source_frames)]).astype(np.float64)
    trans = np.stack([motions[c].translations[f] for c, f in zip(source_clips, source_frames)]).astype(np.float64)
    # cross-fade after synthetic transitions: previous clip continued vs the new one
    for t in sorted(int(x) for x in synthetic_at):
        if t <= 0:
            continue
        prev_clip, prev_frame = source_clips[t - 1], int(source_frames[t - 1])
        pm = motions[prev_clip]
        for k in range(blend_frames):
            u = t + k
            if u >= T:
                break
            f = min(prev_frame + 1 + k, pm.num_frames - 1)
            alpha = 0.5 - 0.5 * np.cos(np.pi * (k + 1) / (blend_frames + 1))  # 0 -> 1
            rot[u, 1:] = np.asarray(quat_slerp(pm.rotations[f, 1:], rot[u, 1:], alpha))
    # root: per-source-frame local velocity and yaw rate
    vel_local = np.zeros((T, 3))
    yaw_rate = np.zeros(T)
    for t, (c, f) in enumerate(zip(source_clips, source_frames)):
        m = motions[c]
        f0, f1 = (f, f + 1) if f + 1 < m.num_frames else (max(f - 1, 0), f)
        y0, y1 = _yaw_angle(m.rotations[f0, 0]), _yaw_angle(m.rotations[f1, 0])
        d = m.translations[f1, 0] - m.translations[f0, 0]
        vel_local[t] = Rotation.from_rotvec([0, -y0, 0]).apply(d)
        yaw_rate[t] = (y1 - y0 + np.pi) % (2 * np.pi) - np.pi
    heading = np.deg2rad(chair_yaw_deg) + np.concatenate([[0.0], np.cumsum(yaw_rate[:-1])])
    pos = np.zeros((T, 3))
    pos[0] = chair
    for t in range(1, T):
        pos[t] = pos[t - 1] + Rotation.from_rotvec([0, heading[t - 1], 0]).apply(vel_local[t - 1])
    pos[:, 1] = trans[:, 0, 1]  # height from the source frames
    src_yaw = _yaw_angle(rot[:, 0])
    tilt = _qmul(_yaw_quat(-src_yaw), rot[:, 0])
    root = Rotation.from_quat(_yaw_quat(heading)[:, [1, 2, 3, 0]]) * tilt
    rot[:, 0] = root.as_quat()[:, [3, 0, 1, 2]]
    trans[:, 0] = pos
    return Motion(skel, rot, trans, float(fps), "synthesized")
