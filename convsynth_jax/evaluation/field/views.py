"""What the metrics read of one window of motion, in one metric scope.

``body``: every joint but those matching ``metrics.joints.exclude`` (default the fingers);
``head``: the head point alone (the End Site above the head joint, ``annotate.motion.head_point``),
the scope of systems that animate the head only (``SynthesisSystem.produces_hands`` False).
Global positions feed the GENEA statistics (jerk, acceleration, histograms); root-relative,
heading-free positions (root at the origin, the root's yaw undone) feed the rest.
"""
from __future__ import annotations

import re
from typing import NamedTuple

import numpy as np

from .params import JointSetParams

SCOPES = ("body", "head")


class MotionView(NamedTuple):
    """global_positions, relative: (F, P, 3) float64; parents: (P,) parent index within the view
    (-1 for none), for the bones of gesture area coverage; upper: indices of the upper-body points
    (beat consistency)."""

    global_positions: np.ndarray
    relative: np.ndarray
    parents: tuple
    upper: tuple


def body_joints(names, joints: JointSetParams) -> tuple[list[int], list[int]]:
    """(kept joint indices, upper-body ones among them, as indices into the kept list)."""
    ex = re.compile(joints.exclude, re.IGNORECASE)
    low = re.compile(joints.lower_body, re.IGNORECASE)
    keep = [j for j, n in enumerate(names) if not ex.search(n)]
    upper = [k for k, j in enumerate(keep) if not low.search(names[j]) and j != 0]
    return keep, upper


def _view_parents(parents, keep) -> tuple:
    pos = {j: k for k, j in enumerate(keep)}
    out = []
    for j in keep:
        p = parents[j]
        while p >= 0 and p not in pos:
            p = parents[p]
        out.append(pos[p] if p >= 0 else -1)
    return tuple(out)


def motion_view(motion, scope: str, joints: JointSetParams, annotate_params) -> MotionView:
    """The :class:`MotionView` of ``motion`` in ``scope``."""
    from ...kinematics import global_transforms
    from ...rotations import rotate_about_y_np, yaw_angle_np

    pos, rot = global_transforms(motion)
    pos = np.asarray(pos, np.float64)
    rot = np.asarray(rot, np.float64)
    yaw = yaw_angle_np(rot[:, 0])                           # (F,) root heading
    if scope == "head":
        from ...annotate.motion import head_point

        g = np.asarray(head_point(motion, annotate_params), np.float64)[:, None, :]
        rel = rotate_about_y_np(g - pos[:, :1], -yaw[:, None])
        return MotionView(g, rel, (-1,), (0,))
    if scope != "body":
        raise ValueError(f"unknown metric scope {scope!r}; scopes are {SCOPES}")
    keep, upper = body_joints(motion.skeleton.names, joints)
    g = pos[:, keep]
    rel = rotate_about_y_np(g - pos[:, :1], -yaw[:, None])
    return MotionView(g, rel, _view_parents(motion.skeleton.parents, keep), tuple(upper))
