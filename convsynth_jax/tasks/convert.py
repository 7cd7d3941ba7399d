"""Task ``convert``: a motion file to BVH.

``convsynth task=convert path=IN task.out=OUT.bvh`` reads any supported motion file (BVH, or an
SMPL-X/SMPL-H parameter ``.npz`` as BEAT2 and AMASS ship them: :mod:`convsynth_jax.io.smplx`) and
writes it as BVH at ``task.fps`` (default 30) in centimetres, SMPL-X joint names for an ``.npz``.
``task.smplx_model=FILE`` (the user's SMPL-X model, ``.npz`` or ``.pkl``) gives an ``.npz`` take its
exact rest joints from its betas; without it the generic template skeleton stands in (approximate
bone lengths; rotations and root translation are the recording's). ``task.out`` defaults to
``<input name>.bvh`` in the run's output folder. The BVH is written atomically.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

from ..errors import ConfigError

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ConvertSettings:
    """``conf/task/convert.yaml`` (the input file: top-level ``path``)."""

    name: str = "convert"
    out: Optional[str] = None            # the BVH to write; null = <out_dir>/<input stem>.bvh
    fps: float = 30.0                    # frame rate of the BVH (resampled: slerp, linear root)
    smplx_model: Optional[str] = None    # SMPL-X model file for exact rest joints of an .npz take


def run(cfg, out_dir: Path) -> dict:
    from ..config import task_settings
    from ..io import save_bvh
    from ..io.motion import load_motion_file

    task = task_settings(cfg)
    if not cfg.get("path"):
        raise ConfigError("task=convert needs path=FILE (.bvh or an SMPL-X .npz)")
    if not task.fps > 0:
        raise ConfigError(f"task.fps must be positive, got {task.fps}", where="task.fps")
    src = Path(str(cfg.path))
    out = Path(task.out) if task.out else Path(out_dir) / f"{src.stem}.bvh"
    if out.suffix.lower() != ".bvh":
        raise ConfigError(f"task.out must name a .bvh file, got {out}", where="task.out")
    motion = load_motion_file(src, fps=task.fps, smplx_model=task.smplx_model)
    save_bvh(motion, out)
    log.info("%s -> %s: %d frames at %g fps, %d joints", src, out, motion.num_frames, motion.fps,
             motion.skeleton.num_joints)
    return {"path": str(src), "out": str(out), "num_frames": motion.num_frames, "fps": motion.fps,
            "duration_s": motion.duration, "num_joints": motion.skeleton.num_joints,
            "joints": list(motion.skeleton.names),
            "rest_skeleton": ("smplx_model" if task.smplx_model else "template") if src.suffix.lower() == ".npz"
            else "file"}
