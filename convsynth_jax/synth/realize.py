"""Realization (paper Section 7.1): poses along a path, root integrated from velocities, blending.

* Joint rotations come from the source frames. At every synthetic transition the following
  ``blend_frames`` output frames are cross-faded with cosine weights from the *displayed* pose
  continued along the previous source clip into the new source, slerping every joint rotation.
  The old stream starts from the pose actually displayed at the frame before the transition (which
  may itself be mid-blend) and moves by the previous clip's own frame-to-frame change
  (``displayed * inverse(source[f]) * source[f + 1 + k]``), so transitions inside an ongoing blend
  compose instead of popping back to a raw source pose. After a single transition (the displayed
  pose is the raw source) this is the plain cross-fade of the previous clip's continuation.
* The root's ground-plane velocity and yaw rate are taken from each source frame in its own heading
  frame and integrated from a chair placement (position and heading); its height and its tilt
  (rotation without heading) come from the source frame and are blended across synthetic
  transitions the same way (tilt by slerp, height linearly).
"""
from __future__ import annotations

import numpy as np

from ..rotations import (quat_conjugate_np, quat_multiply_np, quat_slerp_np, rotate_about_y_np, yaw_angle_np,
                         yaw_to_quat_np)
from ..skeleton import Motion


def blend_weight(k: int, blend_frames: int) -> float:
    """Cosine weight of the new source at the k-th frame (k = 0..blend_frames-1) after a transition."""
    return 0.5 - 0.5 * np.cos(np.pi * (k + 1) / (blend_frames + 1))


def _tilt(q: np.ndarray) -> np.ndarray:
    """Root rotation without its heading (yaw about +Y): (..., 4)."""
    return quat_multiply_np(yaw_to_quat_np(-yaw_angle_np(q)), q)


def composed_blend(source: np.ndarray, source_at, prev_of, synthetic_at, blend_frames: int, rotations: bool
                   ) -> np.ndarray:
    """Blend one channel across synthetic transitions, composing transitions inside a blend.

    source: (T, ...) the raw per-output-frame values (quaternions (T, ..., 4) when ``rotations``,
    else additive values); source_at(clip, frame) -> the value of any source frame; prev_of(t) ->
    (clip, frame, num_frames) of output frame t - 1's source. Returns the displayed values (T, ...)."""
    out = np.array(source, dtype=np.float64, copy=True)
    T = out.shape[0]
    syn = sorted({int(x) for x in synthetic_at if 0 < int(x) < T})
    if blend_frames <= 0 or not syn:
        return out
    for i, t in enumerate(syn):
        clip, f, n = prev_of(t)
        base = out[t - 1]                       # displayed (possibly mid-blend) pose before the jump
        ref = source_at(clip, f)
        stop = min(t + blend_frames, T)
        for u in range(t, stop):
            k = u - t
            nxt = source_at(clip, min(f + 1 + k, n - 1))
            a = blend_weight(k, blend_frames)
            if rotations:
                cont = quat_multiply_np(base, quat_multiply_np(quat_conjugate_np(ref), nxt))
                out[u] = quat_slerp_np(cont, source[u], np.full(source[u].shape[:-1], a))
            else:
                out[u] = (1 - a) * (base + (nxt - ref)) + a * source[u]
        # frames after this blend that a later transition does not take over keep the raw source
    return out


def realize(source_clips, source_frames, motions: dict, synthetic_at, chair=(0.0, 0.0, 0.0), chair_yaw_deg=0.0,
            blend_frames: int = 6) -> Motion:
    """source_clips/source_frames: (T,) clip name and frame per output frame; motions: clip name ->
    Motion; synthetic_at: output frames t whose transition (t-1 -> t) is synthetic."""
    T = len(source_frames)
    m0 = motions[source_clips[0]]
    skel, fps = m0.skeleton, m0.fps
    rot = np.stack([motions[c].rotations[f] for c, f in zip(source_clips, source_frames)]).astype(np.float64)
    trans = np.stack([motions[c].translations[f] for c, f in zip(source_clips, source_frames)]).astype(np.float64)

    def prev_of(t):
        c = source_clips[t - 1]
        return c, int(source_frames[t - 1]), motions[c].num_frames

    # joints below the root, the root's tilt and its height: cross-faded after synthetic transitions
    rot[:, 1:] = composed_blend(rot[:, 1:], lambda c, f: np.asarray(motions[c].rotations[f, 1:], np.float64),
                                prev_of, synthetic_at, blend_frames, rotations=True)
    tilt = composed_blend(_tilt(rot[:, 0]), lambda c, f: _tilt(np.asarray(motions[c].rotations[f, 0], np.float64)),
                          prev_of, synthetic_at, blend_frames, rotations=True)
    height = composed_blend(trans[:, 0, 1], lambda c, f: float(motions[c].translations[f, 0, 1]), prev_of,
                            synthetic_at, blend_frames, rotations=False)
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
    pos[:, 1] = height
    rot[:, 0] = quat_multiply_np(yaw_to_quat_np(heading), tilt)
    trans[:, 0] = pos
    return Motion(skel, rot, trans, float(fps), "synthesized")
