"""Retiming a realized path (``search.retime_factor``, ours; the paper's future work, Section 9).

The search may match an input clause with a source clause whose duration differs by up to the
retiming factor (``search/constraints.py``); ``search/retime.retime_knots`` gives the
piecewise-linear warp that puts each matched segment's start, F0 peak and end on the input's.
:func:`warp_motion` resamples the realized motion through it: output frame t shows the motion at
time tau(t) = np.interp(t, out_knots, path_knots), between frames floor(tau) and floor(tau) + 1,
joint rotations by slerp (``rotations.quat_slerp_np``) and translations (the root's position
included) linearly. The warp is applied after the blends and the root's integration, so a
stretched stretch of motion moves more slowly and a compressed one faster, along the same track.
"""
from __future__ import annotations

import numpy as np

from ..errors import ConfigError
from ..rotations import quat_slerp_np
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


def warp_motion(motion: Motion, out_knots, path_knots) -> Motion:
    """``motion`` resampled through the warp (module docstring); the same number of frames."""
    T = motion.num_frames
    tau = warp_times(T, out_knots, path_knots)
    i0 = np.clip(np.floor(tau).astype(np.int64), 0, T - 1)
    i1 = np.minimum(i0 + 1, T - 1)
    a = tau - i0
    rot = np.asarray(motion.rotations, np.float64)
    trans = np.asarray(motion.translations, np.float64)
    J = rot.shape[1]
    r = quat_slerp_np(rot[i0], rot[i1], np.broadcast_to(a[:, None], (T, J)))
    tr = (1.0 - a)[:, None, None] * trans[i0] + a[:, None, None] * trans[i1]
    return Motion(motion.skeleton, r.astype(motion.rotations.dtype), tr.astype(motion.translations.dtype),
                  motion.fps, motion.name)
