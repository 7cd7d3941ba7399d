"""Motion database of one character: every frame of its clips with root-relative pose features and
the audio status of its own and its partner's channel."""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..annotate.types import FrameAudio
from ..errors import GraphError, MissingFileError
from ..kinematics import batched_pose_features
from ..rotations import joint_turn_deg_np
from .params import FeatureParams

log = logging.getLogger(__name__)


@dataclass
class MotionDatabase:
    """N frames of C clips. positions, velocities: (N, J, 3) float32 root-relative features;
    weights: (J,) joint weights w_b; clip: (N,) clip index; frame: (N,) frame in the clip;
    offsets: (C + 1,) first frame of each clip; own/partner: FrameAudio over all N frames (segment
    indices are clip-frame indices)."""

    clip_names: tuple
    fps: float
    positions: np.ndarray
    velocities: np.ndarray
    weights: np.ndarray
    clip: np.ndarray
    frame: np.ndarray
    offsets: np.ndarray
    own: FrameAudio
    partner: FrameAudio
    joint_names: tuple = ()
    meta: dict = field(default_factory=dict)
    # (N,) the largest turn (degrees) of any joint from the clip's previous frame (0 at a clip's first
    # frame; rotations.joint_turn_deg_np): what the glitch filter reads (graph/seams.py); None: unknown
    joint_turn: np.ndarray | None = None

    @property
    def num_frames(self) -> int:
        return int(self.clip.shape[0])


def _idle(n: int) -> FrameAudio:
    return FrameAudio(np.zeros(n, np.int8), np.full(n, -1, np.int32), np.full(n, -1, np.int32), np.full(n, -1, np.int32))


def build_database(clips, features: FeatureParams | None = None) -> MotionDatabase:
    """clips: iterable of (name, Motion, own FrameAudio or None, partner FrameAudio or None), all of
    one skeleton and frame rate. ``features`` None: the default FeatureParams."""
    features = features if features is not None else FeatureParams()
    up, remove_yaw = int(features.up_axis), bool(features.remove_yaw)
    names, motions, CL, FR, own, partner = [], [], [], [], [], []
    skel = fps = None
    for c, (name, motion, o, p) in enumerate(clips):
        if skel is None:
            skel, fps = motion.skeleton, motion.fps
        elif motion.skeleton.names != skel.names:
            raise GraphError(f"clip {name!r} has another skeleton than {names[0]!r}")
        elif abs(motion.fps - fps) > 1e-6:
            raise GraphError(f"clip {name!r} is at {motion.fps} fps, the others at {fps}")
        n = motion.num_frames
        names.append(name)
        motions.append(motion)
        CL.append(np.full(n, c, np.int32))
        FR.append(np.arange(n, dtype=np.int32))
        for lst, fa in ((own, o), (partner, p)):
            fa = fa if fa is not None else _idle(n)
            if fa.num_frames != n:
                raise GraphError(f"clip {name!r}: audio status has {fa.num_frames} frames, motion {n}")
            lst.append(fa)
    if not names:
        raise GraphError("no clips to build a motion database from")
    overrides = dict(features.joint_weight_overrides or {})
    pattern = features.finger_pattern
    from ..rig import FINGER_PATTERN

    weights = skel.joint_weights(pattern or FINGER_PATTERN, overrides, float(features.finger_weight))
    cat = lambda fs, k: np.concatenate([getattr(x, k) for x in fs])  # noqa: E731
    fa = lambda fs: FrameAudio(cat(fs, "label"), cat(fs, "seg_start"), cat(fs, "seg_end"), cat(fs, "seg_peak"))  # noqa: E731
    lengths = [len(c) for c in CL]
    P, V = batched_pose_features(motions, up, remove_yaw)
    turn = np.concatenate([np.concatenate([[0.0], joint_turn_deg_np(m.rotations)]) for m in motions])
    return MotionDatabase(tuple(names), float(fps), P, V, weights,
                          np.concatenate(CL), np.concatenate(FR), np.concatenate([[0], np.cumsum(lengths)]),
                          fa(own), fa(partner), tuple(skel.names),
                          {"remove_yaw": remove_yaw, "up_axis": up,
                           "root_relative": "positions minus root position, rotated by the inverse root heading"
                                            if remove_yaw else "positions minus root position"},
                          joint_turn=turn.astype(np.float32))


def bvh_folder_clips(root, pattern: str = "**/*.bvh", fps: float = 30):
    """(name, Motion, None, None) for every BVH file under ``root`` (motion only)."""
    from ..io import load_bvh

    root = Path(root)
    if not root.is_dir():
        raise MissingFileError("BVH folder not found", root)
    files = sorted(root.glob(pattern))
    if not files:
        raise GraphError(f"no files matching {pattern!r}", root)
    return [(str(f.relative_to(root)), load_bvh(f, fps=fps), None, None) for f in files]
