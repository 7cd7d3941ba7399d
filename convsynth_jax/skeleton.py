"""Skeleton (joint tree) and Motion (per-frame local transforms) containers.

Both are frozen dataclasses registered as JAX pytrees: numeric arrays are leaves, names, parents
and channel layouts are static (hashable) fields, so kernels jit on the topology.
"""
from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass
from typing import Sequence

import jax
import numpy as np

from .rig import FINGER_PATTERN


@dataclass(frozen=True)
class Skeleton:
    """A joint tree in BVH order (every parent precedes its children).

    names: (J,) joint names; parents: (J,) parent index, -1 for the root;
    offsets: (J, 3) rest offsets from the parent in the file's units;
    channels: per joint, the BVH channel names as written (e.g. ("Zrotation", "Xrotation", "Yrotation"));
    end_sites: (parent joint index, (3,) offset) for every End Site, kept for faithful export.
    """

    names: tuple[str, ...]
    parents: tuple[int, ...]
    offsets: np.ndarray
    channels: tuple[tuple[str, ...], ...]
    end_sites: tuple[tuple[int, tuple[float, float, float]], ...] = ()

    def __post_init__(self):
        if len(self.names) != len(self.parents) or len(self.names) != len(self.channels):
            raise ValueError("names, parents and channels must have one entry per joint")
        for j, p in enumerate(self.parents):
            if p >= j:
                raise ValueError(f"joint {self.names[j]!r}: parent index {p} must precede it")

    @property
    def num_joints(self) -> int:
        return len(self.names)

    def index(self, name: str) -> int:
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"no joint named {name!r}; joints are {list(self.names)}") from None

    def find(self, *patterns: str) -> int | None:
        """Index of the first joint whose name matches any regex (case-insensitive), else None."""
        for pat in patterns:
            rx = re.compile(pat, re.IGNORECASE)
            for j, n in enumerate(self.names):
                if rx.search(n):
                    return j
        return None

    def below(self, joints) -> set[int]:
        """Every joint with one of ``joints`` among its ancestors (not the given joints themselves)."""
        top = {int(j) for j in joints}
        out = set()
        for j in range(len(self.parents)):
            a = self.parents[j]
            while a >= 0:
                if a in top:
                    out.add(j)
                    break
                a = self.parents[a]
        return out

    def children(self, j: int) -> list[int]:
        return [k for k, p in enumerate(self.parents) if p == j]

    def joint_weights(self, finger_pattern: str | None = FINGER_PATTERN,
                      overrides: dict[str, float] | None = None, finger_weight: float = 0.0) -> np.ndarray:
        """Per-joint weights w_b of Eq. 4: 1 by default, ``finger_weight`` (the paper: 0) for joints
        matching ``finger_pattern``; ``overrides`` (joint name -> weight) last."""
        w = np.ones(self.num_joints, dtype=np.float64)
        if finger_pattern:
            rx = re.compile(finger_pattern, re.IGNORECASE)
            for j, n in enumerate(self.names):
                if rx.search(n):
                    w[j] = float(finger_weight)
        for name, value in (overrides or {}).items():
            w[self.index(name)] = float(value)
        return w

    def rotation_order(self, j: int) -> str:
        return "".join(c[0].upper() for c in self.channels[j] if c.lower().endswith("rotation"))

    def has_position_channels(self, j: int) -> bool:
        return any(c.lower().endswith("position") for c in self.channels[j])


jax.tree_util.register_pytree_node(
    Skeleton,
    lambda s: ((s.offsets,), (s.names, s.parents, s.channels, s.end_sites)),
    lambda aux, ch: Skeleton(aux[0], aux[1], ch[0], aux[2], aux[3]),
)


@dataclass(frozen=True)
class Motion:
    """Per-frame local joint transforms.

    rotations: (F, J, 4) local rotations as unit quaternions (w, x, y, z);
    translations: (F, J, 3) local translations: the channel values for joints with position
        channels (the root at least), the skeleton offset otherwise;
    fps: frames per second; name: where it came from (a path or a label).
    """

    skeleton: Skeleton
    rotations: np.ndarray
    translations: np.ndarray
    fps: float
    name: str = ""

    @property
    def num_frames(self) -> int:
        return int(self.rotations.shape[0])

    @property
    def duration(self) -> float:
        return self.num_frames / float(self.fps)

    @property
    def root_positions(self) -> np.ndarray:
        """(F, 3) root translation per frame."""
        return np.asarray(self.translations[:, 0])

    def slice(self, start: int, stop: int) -> "Motion":
        return dataclasses.replace(self, rotations=self.rotations[start:stop], translations=self.translations[start:stop])

    def resample(self, fps: float) -> "Motion":
        """Resample to ``fps``: slerp for rotations, linear for translations."""
        from .rotations import quat_slerp  # local import keeps this module light

        if fps <= 0:
            raise ValueError(f"target fps must be positive, got {fps}")
        if abs(fps - self.fps) < 1e-9 or self.num_frames < 2:
            return dataclasses.replace(self, fps=float(fps))
        n_out = int(np.floor((self.num_frames - 1) * fps / self.fps + 1e-9)) + 1
        t = np.arange(n_out) * (self.fps / fps)
        i0 = np.clip(np.floor(t).astype(int), 0, self.num_frames - 1)
        i1 = np.clip(i0 + 1, 0, self.num_frames - 1)
        a = (t - i0)[:, None]
        rot = np.asarray(quat_slerp(self.rotations[i0], self.rotations[i1], np.broadcast_to(a, i0.shape + (self.skeleton.num_joints,))))
        trans = self.translations[i0] * (1 - a[..., None]) + self.translations[i1] * a[..., None]
        return Motion(self.skeleton, rot.astype(self.rotations.dtype), trans, float(fps), self.name)

    @staticmethod
    def concatenate(motions: Sequence["Motion"]) -> "Motion":
        first = motions[0]
        return Motion(first.skeleton, np.concatenate([m.rotations for m in motions]),
                      np.concatenate([m.translations for m in motions]), first.fps, first.name)


jax.tree_util.register_pytree_node(
    Motion,
    lambda m: ((m.skeleton, m.rotations, m.translations), (m.fps, m.name)),
    lambda aux, ch: Motion(ch[0], ch[1], ch[2], aux[0], aux[1]),
)
