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

from ..rotations import quat_multiply_np, quat_slerp, rotate_about_y_np, yaw_angle_np, yaw_to_quat_np
from ..skeleton import Motion


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
    q0, q1, d = np.zeros((T, 4)), np.zeros((T, 4)), np.zeros((T, 3))
    for t, (c, f) in enumerate(zip(source_clips, source_frames)):
        m = motions[c]
        f0, f1 = (f, f + 1) if f + 1 < m.num_frames else (max(f - 1, 0), f)
        q0[t], q1[t] = m.rotations[f0, 0], m.rotations[f1, 0]
        d[t] = m.translations[f1, 0] - m.translations[f0, 0]
    y0 = yaw_angle_np(q0)
    vel_local = rotate_about_y_np(d, -y0)  # the source frame's step in its own heading frame
    yaw_rate = (yaw_angle_np(q1) - y0 + np.pi) % (2 * np.pi) - np.pi
    heading = np.deg2rad(chair_yaw_deg) + np.concatenate([[0.0], np.cumsum(yaw_rate[:-1])])
    steps = rotate_about_y_np(vel_local[:-1], heading[:-1])
    pos = np.asarray(chair, dtype=np.float64) + np.concatenate([np.zeros((1, 3)), np.cumsum(steps, axis=0)])
    pos[:, 1] = trans[:, 0, 1]  # height from the source frames
    tilt = quat_multiply_np(yaw_to_quat_np(-yaw_angle_np(rot[:, 0])), rot[:, 0])
    rot[:, 0] = quat_multiply_np(yaw_to_quat_np(heading), tilt)
    trans[:, 0] = pos
    return Motion(skel, rot, trans, float(fps), "synthesized")
