"""Hands inside the torso (ours: the paper has no such check): the distance of each hand (the wrist
joint) from the torso's axis, the hips-neck segment. The evaluation calibrates the radius under
which a hand counts as inside from the recorded clips (``evaluate.torso_radius``)."""
from __future__ import annotations

import numpy as np

from .body import Body


def _segment_distance(p, a, b):
    ab = b - a
    t = np.clip(np.sum((p - a) * ab, -1) / np.maximum(np.sum(ab * ab, -1), 1e-12), 0, 1)
    return np.linalg.norm(p - (a + t[..., None] * ab), axis=-1)


def hand_torso_distance(pos: np.ndarray, body: Body, frames=None) -> np.ndarray:
    """(n, 2) distance (cm) of the left and right hand (the wrist joint) from the torso's axis, the
    hips-neck segment, over ``frames`` of ``pos`` (F, J, 3) (default all). A hand is inside the
    torso when this is under the torso radius (``evaluate.torso_radius``)."""
    fr = slice(None) if frames is None else frames
    a, b = pos[fr, body.joints["hips"]], pos[fr, body.joints["neck"]]
    return np.stack([_segment_distance(pos[fr, body.joints[f"hand_{s}"]], a, b) for s in ("l", "r")], axis=-1)
