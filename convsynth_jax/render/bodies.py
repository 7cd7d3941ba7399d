"""Bodies to draw: world positions and the bone tree, their stature and the way they face."""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..errors import ConvSynthError


@dataclass(frozen=True)
class DrawnBody:
    """One character to draw. positions: (frames, joints, 3) world positions (Y up); parents:
    (joints,) parent index (-1 root, -2 not drawn); head, hands: joint indices (None / empty where
    the rig has none); torso: joints on the root-to-head chain (their bones are drawn thicker);
    shoulders: (left, right) joints (the facing direction, drawn as a nose; empty: no nose);
    size: the stature every radius is a fraction of (None: from the bones, :func:`stature`);
    color: index into BODY_RGB (None: the body's place in its panel)."""

    positions: np.ndarray
    parents: tuple[int, ...]
    head: int | None = None
    hands: tuple[int, ...] = ()
    torso: frozenset = frozenset()
    shoulders: tuple[int, ...] = ()
    name: str = ""
    size: float | None = None
    color: int | None = None

    @property
    def num_frames(self) -> int:
        return int(self.positions.shape[0])


def stature(body: DrawnBody) -> float:
    """Bone lengths (frame 0) along the tree from the head down to the lowest joint: a body's height
    whether it sits or stands, whatever lies above the hips (a static world root joint adds
    nothing). Falls back to the vertical extent."""
    if body.size is not None:
        return float(body.size)
    p = np.asarray(body.positions[0], np.float64)
    par = body.parents

    def chain(j):   # {joint: bone length from it up to j} along the path to the root
        out, n = {}, 0.0
        while j is not None and j >= 0:
            out[j] = n
            if par[j] < 0:
                break
            n += float(np.linalg.norm(p[j] - p[par[j]]))
            j = par[j]
        return out

    top = body.head if body.head is not None else int(np.argmax(p[:, 1]))
    ends = [j for j in range(len(par)) if par[j] >= 0]          # joints that end a drawn bone (not the root)
    low = min(ends, key=lambda j: p[j, 1]) if ends else 0
    up, down = chain(top), chain(low)
    common = [j for j in down if j in up]
    s = min((up[j] + down[j] for j in common), default=0.0)
    return s if s > 1e-9 else float(np.ptp(p[:, 1]) or 1.0)


def body_from_motion(motion, name: str = "", color: int | None = None) -> DrawnBody:
    """A :class:`DrawnBody` from a :class:`~convsynth_jax.skeleton.Motion` (forward kinematics and the rig's
    roles, :func:`convsynth_jax.rig.find_role`). Joints below a hand (fingers) are not drawn: the
    hand disc stands for them."""
    from ..kinematics import forward_kinematics_np
    from ..rig import find_role

    sk = motion.skeleton
    pos = np.asarray(forward_kinematics_np(motion), dtype=np.float32)
    if not np.all(np.isfinite(pos)):
        raise ConvSynthError(f"forward kinematics gives non-finite joint positions (body {name!r})")
    parents = tuple(int(p) for p in sk.parents)
    head = find_role(sk, "head")
    hands = tuple(j for j in (find_role(sk, "left_hand"), find_role(sk, "right_hand")) if j is not None)
    shoulders = tuple(j for j in (find_role(sk, "left_shoulder"), find_role(sk, "right_shoulder")) if j is not None)
    torso = set()
    j = head if head is not None else int(np.argmax(pos[0, :, 1]))
    while j >= 0:
        torso.add(j)
        j = parents[j]
    below_hand = sk.below(hands)
    kept = tuple(-2 if j in below_hand else p for j, p in enumerate(parents))
    b = DrawnBody(pos, kept, head, hands, frozenset(torso), shoulders if len(shoulders) == 2 else (), name, color=color)
    return replace(b, size=stature(b))


def frozen(body: DrawnBody, frame: int = 0) -> DrawnBody:
    """``body`` held at ``frame`` for its whole length (the study's attention checks)."""
    return replace(body, positions=np.repeat(body.positions[frame:frame + 1], body.num_frames, axis=0))


def _facing(body: DrawnBody, frame: int) -> np.ndarray | None:
    """The horizontal unit vector the body faces at ``frame`` (up x (right shoulder - left shoulder)),
    None without shoulders."""
    if len(body.shoulders) != 2:
        return None
    p = body.positions[frame]
    d = np.asarray(p[body.shoulders[1]] - p[body.shoulders[0]], np.float64)
    f = np.array([d[2], 0.0, -d[0]])          # (0, 1, 0) x d
    n = np.linalg.norm(f)
    return f / n if n > 1e-9 else None
