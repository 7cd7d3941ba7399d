"""Smoothness at the splices: the root-relative wrist jerk near the splice boundaries, against the
largest jerk of the source clips (the gesture and the tiled loop)."""
from __future__ import annotations

import numpy as np

from ..kinematics import forward_kinematics_np, jerk
from .body import Body
from .gestures import Phases
from .locomotion import tile_loop
from .pipeline import LoopContext

JERK_WINDOW = 3  # frames either side of a splice boundary


def wrist_jerk(pos: np.ndarray, body: Body, sides, fps: float) -> np.ndarray:
    """(F-3,) largest root-relative wrist jerk (cm/s^3) over ``sides``; entry i covers frames i..i+3."""
    out = None
    for s in sides:
        x = pos[:, body.joints[f"hand_{s}"]] - pos[:, body.joints["hips"]]
        j = np.linalg.norm(jerk(x, fps), axis=-1)
        out = j if out is None else np.maximum(out, j)
    return out


def loop_source_jerk(lc: LoopContext, sides) -> float:
    """The largest wrist jerk (cm/s^3) of ``sides`` over the loop tiled three times (its seams included)."""
    m = tile_loop(lc.loop, 3 * lc.loop.num_frames)
    return float(wrist_jerk(forward_kinematics_np(m), lc.body, sides, m.fps).max())


def boundary_jerk(jerk: np.ndarray, ph: Phases) -> float | None:
    """The largest of ``jerk`` (:func:`wrist_jerk` of a splice) near its boundaries t_Pb, t_Pe + 1,
    t_Rb and t_Re + 1: from ``2 * JERK_WINDOW`` frames before to ``JERK_WINDOW`` after each; None
    when no window lies inside the timeline."""
    near = []
    for b in (ph.pb, ph.pe + 1, ph.rb, ph.re + 1):
        lo, hi = max(0, b - 2 * JERK_WINDOW), min(len(jerk), b + JERK_WINDOW + 1)
        if hi > lo:
            near.append(jerk[lo:hi].max())
    return max(near) if near else None
