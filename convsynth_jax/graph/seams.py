"""Seam edge filter (ours; option ``graph.seam_filter_quantile``, off by default) and
glitch filter (ours; ``graph.glitch_max_step_deg``, off by default, 15 in preset=quality: :func:`apply_glitch_filter`).

The paper (Section 6) admits every synthetic transition whose cost c(i, j) is below the threshold.
The cost compares poses and velocities (Eq. 3-4) with finger joints weighted 0, so nothing stops a
transition next to a fast stroke of the source motion (a finger flick, a hand beat). Whatever the
blend does, the frames played around such a transition carry that stroke, and a seam measured
there (``evaluation.metrics.seam_ratio``: the largest root-relative acceleration within 3 frames of
a transition) inherits it. On leave-one-out most windows whose seam exceeded the ground truth's
largest acceleration had exactly that: the source content itself was over the limit.

This module drops, when the graph is built, every synthetic transition i -> j whose source frames
i - r .. i + r (the frames played before the jump and the old clip's continuation that the blend
fades out) or destination frames j - r .. j + r (played after it) contain a *fast* frame: one whose
largest root-relative joint acceleration (every joint, fingers included) exceeds the
``quantile`` of that quantity over all frames of the database. Original transitions are never
touched, so fast content still plays, only not at a seam.

    acc[n] = max_b || (p_{n+1}[b] - 2 p_n[b] + p_{n-1}[b]) * fps^2 ||   (central difference, in its clip)

(``kinematics.seam_acceleration``, the definition the evaluation's seam metrics use too.)
"""
from __future__ import annotations

import numpy as np

from ..kinematics import seam_acceleration
from .database import MotionDatabase


def frame_acceleration(db: MotionDatabase) -> np.ndarray:
    """(N,) largest root-relative joint acceleration of every database frame, units / s^2.

    Central second difference of ``db.positions`` (root-relative, heading removed) within each
    clip; a clip's first and last frames take their neighbour's value (a clip of fewer than 3
    frames gets 0)."""
    P = np.asarray(db.positions, np.float64)
    out = np.zeros(db.num_frames)
    for s, e in zip(db.offsets[:-1], db.offsets[1:]):
        s, e = int(s), int(e)
        if e > s:
            out[s:e] = seam_acceleration(P[s:e], float(db.fps)).max(-1)
    return out


def near_fast_frames(db: MotionDatabase, acc: np.ndarray, limit: float, radius: int) -> np.ndarray:
    """(N,) bool: frames with a frame of acceleration over ``limit`` within ``radius`` frames of
    the same clip (the frame itself included)."""
    fast = np.asarray(acc) > limit
    out = fast.copy()
    clip = np.asarray(db.clip)
    n = db.num_frames
    for d in range(1, int(radius) + 1):
        same = clip[d:] == clip[:-d] if n > d else np.zeros(0, bool)
        out[d:] |= fast[:-d] & same    # a fast frame d before
        out[:-d] |= fast[d:] & same    # a fast frame d after
    return out


def seam_filter_mask(db: MotionDatabase, a: np.ndarray, j: np.ndarray, quantile: float, radius: int,
                     acc: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """Which synthetic transitions a -> j (database frame indices, (E,)) the seam filter keeps, and
    the acceleration limit (the ``quantile`` of :func:`frame_acceleration` over the database)."""
    acc = frame_acceleration(db) if acc is None else np.asarray(acc)
    limit = float(np.quantile(acc, float(quantile))) if acc.size else 0.0
    bad = near_fast_frames(db, acc, limit, radius)
    a, j = np.asarray(a, np.int64), np.asarray(j, np.int64)
    return ~(bad[a] | bad[j]), limit


def apply_seam_filter(db: MotionDatabase, a, j, c, params, meta: dict | None = None):
    """(a, j, c) without the transitions the seam filter drops; identity when
    ``params.seam_filter_quantile`` is None (the paper). Records the limit and the counts in
    ``meta`` (``seam_filter``)."""
    q = params.seam_filter_quantile
    if q is None:
        return a, j, c
    keep, limit = seam_filter_mask(db, a, j, q, int(params.seam_filter_radius))
    if meta is not None:
        meta["seam_filter"] = {"quantile": float(q), "radius": int(params.seam_filter_radius),
                               "acceleration_limit": limit, "candidates": int(keep.size),
                               "dropped": int((~keep).sum())}
    return a[keep], j[keep], c[keep]


def glitch_filter_mask(db: MotionDatabase, a: np.ndarray, j: np.ndarray, max_step_deg: float,
                       radius: int) -> np.ndarray:
    """Which synthetic transitions a -> j (database frame indices, (E,)) the glitch filter keeps: those
    with no step of more than ``max_step_deg`` degrees (any joint, ``db.joint_turn``) within ``radius``
    frames of a or of j in the same clip. A step into frame g marks g - 1 and g."""
    turn = np.asarray(db.joint_turn, np.float64)
    step = turn > float(max_step_deg)
    both = step.copy()
    clip = np.asarray(db.clip)
    both[:-1] |= step[1:] & (clip[1:] == clip[:-1])      # the frame before the step
    bad = near_fast_frames(db, both.astype(np.float64), 0.5, radius)
    a, j = np.asarray(a, np.int64), np.asarray(j, np.int64)
    return ~(bad[a] | bad[j])


def apply_glitch_filter(db: MotionDatabase, a, j, c, params, meta: dict | None = None):
    """(a, j, c) without the synthetic transitions next to a glitch (:func:`glitch_filter_mask`; ours, off
    by default: ``graph.glitch_max_step_deg`` 0; preset=quality sets 15). Records the counts in ``meta``
    (``glitch_filter``)."""
    limit = float(params.glitch_max_step_deg)
    if limit <= 0 or db.joint_turn is None:
        return a, j, c
    keep = glitch_filter_mask(db, a, j, limit, int(params.seam_filter_radius))
    if meta is not None:
        meta["glitch_filter"] = {"max_step_deg": limit, "radius": int(params.seam_filter_radius),
                                 "candidates": int(keep.size), "dropped": int((~keep).sum())}
    return a[keep], j[keep], c[keep]
