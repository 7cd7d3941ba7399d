"""Any supported motion file, by its suffix: BVH (``.bvh``) or SMPL-X/SMPL-H parameters (``.npz``)."""
from __future__ import annotations

from pathlib import Path

from ..errors import FormatError, MissingFileError
from ..skeleton import Motion

MOTION_SUFFIXES = (".bvh", ".npz")


def _kind(path: Path) -> str:
    suffix = path.suffix.lower()
    if suffix not in MOTION_SUFFIXES:
        if not path.exists():
            raise MissingFileError("motion file not found", path)
        raise FormatError(f"unsupported motion file type {path.suffix!r} (expected one of {list(MOTION_SUFFIXES)})",
                          path)
    return suffix


def load_motion_file(path: str | Path, fps: float | None = None, smplx_model: str | Path | None = None) -> Motion:
    """The motion in ``path`` (resampled to ``fps`` unless None). ``smplx_model``: the SMPL-X model
    file that gives an ``.npz`` take its exact rest joints (:func:`convsynth_jax.io.smplx.smplx_motion`)."""
    path = Path(path)
    if _kind(path) == ".npz":
        from .smplx import smplx_motion

        return smplx_motion(path, fps=fps, smplx_model=smplx_model)
    from .bvh import load_bvh

    return load_bvh(path, fps=fps)


def motion_file_duration(path: str | Path) -> float:
    """Seconds of motion in ``path`` (a BVH file from its header alone)."""
    path = Path(path)
    if _kind(path) == ".npz":
        from .smplx import smplx_duration

        return smplx_duration(path)
    from .bvh import bvh_duration

    return bvh_duration(path)
