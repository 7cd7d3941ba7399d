"""Retiming a realized path (``search.retime_factor``, ours; the paper's future work, Section 9).

The search may match an input clause with a source clause whose duration differs by up to the
retiming factor (``search/constraints.py``); ``search/retime.retime_knots`` gives the
piecewise-linear warp that puts each matched segment's start, F0 peak and end on the input's.
:func:`warp_motion` resamples the realized motion through it: output frame t shows the motion at
time tau(t) = np.interp(t, out_knots, path_knots), between frames floor(tau) and floor(tau) + 1,
joint rotations by slerp (``rotations.quat_slerp_np``) and translations (the root's position
included) linearly. The warp is applied after the blends and the root's integration, so a
stretched stretch of motion moves more slowly and a compressed one faster, along the same track.

``synth.retime_min_speed`` (ours, 0 = off): the warp returns to the identity a short way past a
retimed segment (``search/retime.py``: a knot a <- a in the idle run), which concentrates the
segment's shift into a few idle frames; where that plays the path slower than this speed,
:func:`spread_slow_stretches` drops the identity knot, so the shift spreads over the idle run up to the
next knot and the idle motion keeps more of its speed (a slowed calm stretch is where still frames
come from). The matched segments' knots stay, so every matched start, peak and end lands where it did.

``synth.retime_detail_frames`` (ours, 0 = off): a slowed stretch interpolates between neighbouring
frames, which also slows (and so flattens) the recording's frame-to-frame detail: a stretch at 0.7x
of calm motion reads as still. With it, :func:`warp_motion` warps only the motion's moving average
over this many frames and puts the detail (each frame's offset from that average) back at the output
rate, frame t's own detail at output frame t; where the warp is the identity the motion is unchanged.
"""
from __future__ import annotations

import numpy as np

from ..errors import ConfigError
from ..rotations import quat_conjugate_np, quat_multiply_np, quat_slerp_np
from ..skeleton import Motion


def warp_times(num_frames: int, out_knots, path_knots) -> np.ndarray:
    """(T,) the path time shown at each output frame."""
    out_k, path_k = np.asarray(out_knots, np.float64), np.asarray(path_knots, np.float64)
    T = int(num_frames)
    if (out_k.ndim != 1 or out_k.shape != path_k.shape or out_k.size < 2 or np.any(np.diff(out_k) <= 0)
            or np.any(np.diff(path_k) <= 0) or out_k[0] != 0 or path_k[0] != 0 or out_k[-1] != T - 1
            or path_k[-1] != T - 1):
        raise ConfigError(f"a retiming warp needs increasing knots from 0 to {T - 1} on both timelines, got "
                          f"output {out_k.tolist()} and path {path_k.tolist()}")
    return np.interp(np.arange(T, dtype=np.float64), out_k, path_k)


def spread_slow_stretches(out_knots, path_knots, min_speed: float):
    """(out_knots, path_knots) with every interior identity knot (a <- a, the warp's return to the
    identity) dropped where a piece next to it plays the path slower than ``min_speed`` (path frames
    per output frame), one at a time, the slowest piece first, while any such knot is left; the other
    knots (the matched segments') stay. ``min_speed`` <= 0: the knots unchanged."""
    out_k, path_k = np.asarray(out_knots, np.float64).copy(), np.asarray(path_knots, np.float64).copy()
    if float(min_speed) <= 0 or out_k.size < 3:
        return out_k, path_k
    while True:
        speed = np.diff(path_k) / np.diff(out_k)                 # piece i: knots i -> i + 1
        ident = np.zeros(out_k.size, bool)
        ident[1:-1] = out_k[1:-1] == path_k[1:-1]
        best, slowest = None, float(min_speed)
        for i in np.flatnonzero(ident):
            s = min(speed[i - 1], speed[i])
            if s < slowest:
                best, slowest = i, s
        if best is None:
            return out_k, path_k
        out_k, path_k = np.delete(out_k, best), np.delete(path_k, best)


def frame_moving_average(x: np.ndarray, frames: int, rotations: bool) -> np.ndarray:
    """(T, ...) centred moving average of ``frames`` frames (ends: the frames there are); quaternions
    sign-aligned to the frame's own and renormalized."""
    T, h = x.shape[0], int(frames) // 2
    out = np.empty_like(x)
    for t in range(T):
        w = x[max(0, t - h):min(T, t + h + 1)]
        if rotations:
            w = np.where(np.sum(w * x[t], axis=-1, keepdims=True) < 0, -w, w)
            m = w.mean(axis=0)
            out[t] = m / np.linalg.norm(m, axis=-1, keepdims=True)
        else:
            out[t] = w.mean(axis=0)
    return out


def _resample(rot, trans, tau):
    T = rot.shape[0]
    i0 = np.clip(np.floor(tau).astype(np.int64), 0, T - 1)
    i1 = np.minimum(i0 + 1, T - 1)
    a = tau - i0
    r = quat_slerp_np(rot[i0], rot[i1], np.broadcast_to(a[:, None], rot.shape[:2]))
    tr = (1.0 - a)[:, None, None] * trans[i0] + a[:, None, None] * trans[i1]
    return r, tr


def warp_motion(motion: Motion, out_knots, path_knots, detail_frames: int = 0) -> Motion:
    """``motion`` resampled through the warp (module docstring); the same number of frames.
    ``detail_frames`` > 1: only the moving average over that many frames is warped, each frame's
    detail (its offset from the average: a left rotation per joint, a difference of translations)
    goes back at its own output frame."""
    T = motion.num_frames
    tau = warp_times(T, out_knots, path_knots)
    rot = np.asarray(motion.rotations, np.float64)
    trans = np.asarray(motion.translations, np.float64)
    if int(detail_frames) > 1:
        rot_avg, trans_avg = frame_moving_average(rot, detail_frames, True), frame_moving_average(trans, detail_frames, False)
        r, tr = _resample(rot_avg, trans_avg, tau)
        r = quat_multiply_np(quat_multiply_np(rot, quat_conjugate_np(rot_avg)), r)
        tr = tr + (trans - trans_avg)
    else:
        r, tr = _resample(rot, trans, tau)
    return Motion(motion.skeleton, r.astype(motion.rotations.dtype), tr.astype(motion.translations.dtype),
                  motion.fps, motion.name)
