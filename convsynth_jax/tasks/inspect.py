"""Task ``inspect``: report what a motion file (``path=FILE``: BVH or an SMPL-X ``.npz``) or the
configured corpus holds."""
from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..io.motion import load_motion_file
from ..kinematics import forward_kinematics

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class InspectSettings:
    """``conf/task/inspect.yaml`` (the file: top-level ``path``)."""

    name: str = "inspect"


def run(cfg, out_dir: Path) -> dict:
    if cfg.get("path"):
        motion = load_motion_file(cfg.path)
        pos = np.asarray(forward_kinematics(motion))
        summary = {
            "path": str(cfg.path),
            "num_frames": motion.num_frames,
            "fps": motion.fps,
            "duration_s": motion.duration,
            "num_joints": motion.skeleton.num_joints,
            "joints": list(motion.skeleton.names),
            "bbox_min": pos.reshape(-1, 3).min(0).tolist(),
            "bbox_max": pos.reshape(-1, 3).max(0).tolist(),
        }
        log.info("%s: %d frames at %.3g fps, %d joints", cfg.path, motion.num_frames, motion.fps,
                 motion.skeleton.num_joints)
        return summary
    from .common import open_corpus, params_of

    corpus = open_corpus(params_of(cfg))
    rows = []
    for s in corpus.sessions:
        for p in s.participants:
            rows.append({"session": s.name, "role": p.role, "character": p.character})
    return {"corpus_root": str(corpus.root), "num_sessions": len(corpus.sessions), "participants": rows}
