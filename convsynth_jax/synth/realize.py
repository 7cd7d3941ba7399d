"""Realization (paper Section 7.1): poses along a path, root integrated from velocities, blending.

* Joint rotations come from the source frames. At every synthetic transition the following
  ``blend_frames`` output frames are cross-faded with cosine weights from the stream that would
  have been displayed had the path continued along its previous clip into the new source, slerping
  every joint rotation. A transition inside an ongoing blend nests: its old stream is the
  interrupted blend, whose weight stays at the value last displayed while both of its streams go on
  along their clips (``composed_blend``), so nothing pops back to a raw source pose and a clip
  visited for a frame or two is not played at full weight through the next blend. After a single
  transition this is the plain cross-fade of the previous clip's continuation.
* A continuation holds at the last frame before a step of its clip in which some joint turns more
  than ``max_step_deg`` degrees (ours: a marker-swap glitch of the source is never faded in through
  a blend; :func:`continuation_end`).
* ``detail_frames`` (ours, ``synth.blend_detail_frames``, 0 = off): a cross-fade averages two streams,
  and so flattens the frame-to-frame detail both carry (a blend of calm motion reads as still); with
  it, each blended frame's joint rotations are the blend's moving average over this many frames with
  the new source's own detail (its offset from its moving average within its run) put back
  (:func:`keep_source_detail`).
* The root's ground-plane velocity and yaw rate are taken from each source frame in its own heading
  frame and integrated from a chair placement (position and heading); its height and its tilt
  (rotation without heading) come from the source frame and are blended across synthetic
  transitions the same way (tilt by slerp, height linearly).
"""
from __future__ import annotations

import numpy as np

from ..easing import cosine
from ..rotations import (joint_turn_deg_np, quat_conjugate_np, quat_multiply_np, quat_slerp_np, rotate_about_y_np,
                         yaw_angle_np, yaw_to_quat_np)
from ..errors import ConfigError
from ..skeleton import Motion


def blend_weight(k: int, blend_frames: int) -> float:
    """Cosine weight of the new source at the k-th frame (k = 0..blend_frames-1) after a transition."""
    return cosine(k + 1, blend_frames + 1)


def _tilt(q: np.ndarray) -> np.ndarray:
    """Root rotation without its heading (yaw about +Y): (..., 4)."""
    return quat_multiply_np(yaw_to_quat_np(-yaw_angle_np(q)), q)


def composed_blend(source: np.ndarray, source_at, prev_of, synthetic_at, blend_frames: int, rotations: bool
                   ) -> np.ndarray:
    """Blend one channel across synthetic transitions, nesting blends that overlap.

    Transition m at output frame t_m starts layer m: the new source cross-faded in with cosine weights
    over ``blend_frames`` frames from layer m - 1, the stream that would have been displayed had the
    path continued along its previous clip. A layer interrupted by the next transition before its
    blend ended keeps, from then on, the weight it had on the last frame it was displayed (ours: the
    paper's blend is for one transition), and each of its two streams goes on along its own clip.
    So a source visited for one frame between two transitions shows with the small weight it was
    displayed with, not at full weight for the next blend (before: the next blend's old stream moved
    with that clip's own motion). With no overlap this is the plain cross-fade of the previous clip's
    continuation into the new source.

    source: (T, ...) the raw per-output-frame values (quaternions (T, ..., 4) when ``rotations``,
    else additive values); source_at(clip, frame) -> the value of any source frame; prev_of(t) ->
    (clip, frame, last) of output frame t - 1's source, ``last`` the last frame its continuation may
    play (the clip's last frame, or the frame before a glitch: :func:`continuation_end`); the
    continuation holds there. Returns the displayed values (T, ...)."""
    out = np.array(source, dtype=np.float64, copy=True)
    T = out.shape[0]
    syn = sorted({int(x) for x in synthetic_at if 0 < int(x) < T})
    if blend_frames <= 0 or not syn:
        return out
    M = len(syn)
    prev = [prev_of(t) for t in syn]         # layer m - 1's clip and frame at t_m - 1

    def raw(m, u):
        """Layer m's own source at output frame u, going on along its clip past transition m + 1."""
        if m + 1 < M and u >= syn[m + 1]:
            clip, f, last = prev[m + 1]
            return np.asarray(source_at(clip, max(f, min(f + 1 + u - syn[m + 1], last))), np.float64)
        return np.asarray(source[u], np.float64)

    memo: dict = {}

    def stream(m, u):
        """What layer m displays at output frame u >= t_m (layer -1: the source before t_0)."""
        key = (m, u)
        if key in memo:
            return memo[key]
        r = raw(m, u)
        if m >= 0:
            k = (min(u, syn[m + 1] - 1) if m + 1 < M else u) - syn[m]   # weight frozen once interrupted
            if k < blend_frames:
                old = stream(m - 1, u)
                a = blend_weight(k, blend_frames)
                if rotations:
                    r = quat_slerp_np(old, r, np.full(r.shape[:-1], a))
                else:
                    r = (1 - a) * old + a * r
        memo[key] = r
        return r

    for m, t in enumerate(syn):
        stop = min(t + blend_frames, T, syn[m + 1] if m + 1 < M else T)
        for u in range(t, stop):
            out[u] = stream(m, u)
        # frames after this blend that a later transition does not take over keep the raw source
    return out


def continuation_end(rotations: np.ndarray, frame: int, max_step_deg: float, horizon: int, steps=None) -> int:
    """The last frame a continuation of a clip from ``frame`` plays (ours): the frame before the first
    step g - 1 -> g (frame < g <= frame + horizon) in which some joint below the root turns more than
    ``max_step_deg`` degrees, else frame + horizon (at most the clip's last frame). rotations: (n, J, 4)
    the clip's rotations; ``max_step_deg`` <= 0: no limit. ``steps``: the clip's
    :func:`large_steps` when known (a realization asks for many continuations of one clip: the turns
    are then computed once per clip, not once per transition over the rest of the clip)."""
    n = rotations.shape[0]
    stop = min(n - 1, int(frame) + int(horizon))
    if max_step_deg <= 0 or stop <= frame:
        return stop
    if steps is not None:
        i = int(np.searchsorted(steps, frame))
        return int(steps[i]) if i < len(steps) and steps[i] < stop else stop
    big = np.flatnonzero(joint_turn_deg_np(rotations[frame:stop + 1]) > max_step_deg)
    return int(frame) + int(big[0]) if big.size else stop


def large_steps(rotations: np.ndarray, max_step_deg: float) -> np.ndarray:
    """Sorted frames g of a clip whose step g -> g + 1 turns some joint below the root more than
    ``max_step_deg`` degrees (what :func:`continuation_end` stops before)."""
    return np.flatnonzero(joint_turn_deg_np(rotations) > max_step_deg)


def _quat_log(q: np.ndarray) -> np.ndarray:
    """Rotation vector (..., 3) of unit quaternions (..., 4) (w, x, y, z), the shorter way round."""
    q = np.where(q[..., :1] < 0, -q, q)
    v = q[..., 1:]
    s = np.linalg.norm(v, axis=-1, keepdims=True)
    ang = 2.0 * np.arctan2(s, q[..., :1])
    return np.where(s > 1e-12, v * ang / np.maximum(s, 1e-300), 2.0 * v)


def _quat_exp(r: np.ndarray) -> np.ndarray:
    """Unit quaternion (..., 4) of rotation vectors (..., 3)."""
    ang = np.linalg.norm(r, axis=-1, keepdims=True)
    half = 0.5 * ang
    k = np.where(ang > 1e-12, np.sin(half) / np.maximum(ang, 1e-300), 0.5)
    return np.concatenate([np.cos(half), r * k], axis=-1)


def quintic_decay(x0, v0, n: int, k):
    """Offset at frame k (0 = the transition's frame) of an inertialization (Bollo 2016, ours here):
    a quintic that starts at ``x0`` with slope ``v0`` (per frame) and the acceleration that keeps
    its jerk low, and reaches 0 with zero slope and acceleration at frame ``n``; 0 from ``n`` on."""
    x0, v0 = np.asarray(x0, np.float64), np.asarray(v0, np.float64)
    if k >= n:
        return np.zeros_like(x0)
    t1 = float(n)
    a0 = -(8.0 * v0 * t1 + 20.0 * x0) / t1 ** 2
    A = -(a0 * t1 ** 2 + 6.0 * v0 * t1 + 12.0 * x0) / (2.0 * t1 ** 5)
    B = (3.0 * a0 * t1 ** 2 + 16.0 * v0 * t1 + 30.0 * x0) / (2.0 * t1 ** 4)
    C = -(3.0 * a0 * t1 ** 2 + 12.0 * v0 * t1 + 20.0 * x0) / (2.0 * t1 ** 3)
    t = float(k)
    return (((A * t + B) * t + C) * t + 0.5 * a0) * t * t + v0 * t + x0


def inertialized_blend(source: np.ndarray, next_of, synthetic_at, blend_frames: int, rotations: bool
                       ) -> np.ndarray:
    """Inertialization across synthetic transitions (ours; option ``synth.blend_method=inertialize``).

    At a transition arriving at t the displayed stream is extrapolated one and two frames on with its
    own last velocity (out[t-1] - out[t-2]); the offsets from the new source at t and t + 1 give the
    offset's value and slope, which a quintic (``quintic_decay``) takes to zero over ``blend_frames``
    frames. The new source plays on top of the decaying offset, so no old clip is cross-faded in and
    the new source's own motion is never damped. A transition inside an ongoing decay starts from the
    displayed pose and velocity, so back-to-back transitions compose. Rotations offset on the left
    as rotation vectors. next_of(t) -> value of the new source one frame after output frame t's."""
    out = np.array(source, dtype=np.float64, copy=True)
    T = out.shape[0]
    syn = sorted({int(x) for x in synthetic_at if 0 < int(x) < T})
    if blend_frames <= 0 or not syn:
        return out
    raw = np.array(source, dtype=np.float64, copy=True)
    for i, t in enumerate(syn):
        stop = syn[i + 1] if i + 1 < len(syn) else T
        prev = out[t - 1]
        prev2 = out[t - 2] if t >= 2 else out[t - 1]
        s0, s1 = raw[t], next_of(t)
        if rotations:
            step = quat_multiply_np(prev, quat_conjugate_np(prev2))          # last displayed rotation step
            e1 = quat_multiply_np(step, prev)
            e2 = quat_multiply_np(step, e1)
            o0 = _quat_log(quat_multiply_np(e1, quat_conjugate_np(s0)))
            o1 = _quat_log(quat_multiply_np(e2, quat_conjugate_np(s1)))
        else:
            v = prev - prev2
            o0, o1 = (prev + v) - s0, (prev + 2 * v) - s1
        x0, v0 = o0, o1 - o0
        for u in range(t, min(stop, T)):
            o = quintic_decay(x0, v0, blend_frames, u - t)
            out[u] = quat_multiply_np(_quat_exp(o), raw[u]) if rotations else raw[u] + o
    return out


def keep_source_detail(blended: np.ndarray, raw: np.ndarray, synthetic_at, blend_frames: int, detail_frames: int
                       ) -> np.ndarray:
    """Rotations (T, J, 4) where every frame within ``blend_frames`` after a synthetic transition is the
    moving average of ``blended`` over ``detail_frames`` frames times the detail of ``raw`` (the source
    played at that frame: its left offset from its own moving average, taken within the run between
    two synthetic transitions so no cut enters it); other frames are ``blended``'s."""
    from .retime import frame_moving_average

    out = np.array(blended, dtype=np.float64, copy=True)
    T = out.shape[0]
    syn = sorted({int(x) for x in synthetic_at if 0 < int(x) < T})
    if detail_frames <= 1 or blend_frames <= 0 or not syn:
        return out
    avg = frame_moving_average(np.asarray(blended, np.float64), detail_frames, True)
    bounds = [0, *syn, T]
    for a, b in zip(bounds[:-1], bounds[1:]):
        if a not in syn:
            continue
        stop = min(b, a + blend_frames)
        run = np.asarray(raw[a:b], np.float64)
        detail = quat_multiply_np(run, quat_conjugate_np(frame_moving_average(run, detail_frames, True)))
        out[a:stop] = quat_multiply_np(detail[:stop - a], avg[a:stop])
    return out


def realize(source_clips, source_frames, motions: dict, synthetic_at, chair=(0.0, 0.0, 0.0), chair_yaw_deg=0.0,
            blend_frames: int = 6, blend_method: str = "cosine", max_step_deg: float = 0.0,
            detail_frames: int = 0) -> Motion:
    """source_clips/source_frames: (T,) clip name and frame per output frame; motions: clip name ->
    Motion; synthetic_at: output frames t whose transition (t-1 -> t) is synthetic; blend_method:
    ``cosine`` (the paper's cross-fade, composed) or ``inertialize`` (ours); ``max_step_deg``: a
    cosine blend's continuations hold before a larger joint step (:func:`continuation_end`; 0: off);
    ``detail_frames``: a cosine blend keeps the new source's frame-to-frame detail (module docstring)."""
    T = len(source_frames)
    m0 = motions[source_clips[0]]
    skel, fps = m0.skeleton, m0.fps
    rot = np.stack([motions[c].rotations[f] for c, f in zip(source_clips, source_frames)]).astype(np.float64)
    trans = np.stack([motions[c].translations[f] for c, f in zip(source_clips, source_frames)]).astype(np.float64)

    steps: dict = {}      # clip -> its large steps, computed on the first continuation of that clip
    ends: dict = {}       # output frame -> prev_of's answer (asked once per blended channel)

    def prev_of(t):
        if t not in ends:
            c, f = source_clips[t - 1], int(source_frames[t - 1])
            if max_step_deg > 0 and c not in steps:
                steps[c] = large_steps(motions[c].rotations, float(max_step_deg))
            ends[t] = c, f, continuation_end(motions[c].rotations, f, float(max_step_deg), T, steps.get(c))
        return ends[t]

    def get_rot(c, f):
        return np.asarray(motions[c].rotations[f, 1:], np.float64)

    def get_tilt(c, f):
        return _tilt(np.asarray(motions[c].rotations[f, 0], np.float64))

    def get_h(c, f):
        return float(motions[c].translations[f, 0, 1])

    if blend_method == "cosine":
        # joints below the root, the root's tilt and its height: cross-faded after synthetic transitions
        raw = rot[:, 1:].copy()
        rot[:, 1:] = composed_blend(raw, get_rot, prev_of, synthetic_at, blend_frames, rotations=True)
        rot[:, 1:] = keep_source_detail(rot[:, 1:], raw, synthetic_at, blend_frames, int(detail_frames))
        tilt = composed_blend(_tilt(rot[:, 0]), get_tilt, prev_of, synthetic_at, blend_frames, rotations=True)
        height = composed_blend(trans[:, 0, 1], get_h, prev_of, synthetic_at, blend_frames, rotations=False)
    elif blend_method == "inertialize":
        def next_of(get):  # the new source one frame after output frame t's (its velocity at t)
            return lambda t: get(source_clips[t], min(int(source_frames[t]) + 1, motions[source_clips[t]].num_frames - 1))

        rot[:, 1:] = inertialized_blend(rot[:, 1:], next_of(get_rot), synthetic_at, blend_frames, rotations=True)
        tilt = inertialized_blend(_tilt(rot[:, 0]), next_of(get_tilt), synthetic_at, blend_frames, rotations=True)
        height = inertialized_blend(trans[:, 0, 1], next_of(get_h), synthetic_at, blend_frames, rotations=False)
    else:
        raise ConfigError(f"synth.blend_method must be 'cosine' or 'inertialize', got {blend_method!r}")
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
