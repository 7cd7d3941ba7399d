"""The perceptual study's stimuli: two panels side by side, no timeline (participants must not see the labels)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import ConvSynthError
from .raster import PanelRenderer
from .video import _step, write_video


def join_panels(left: list, right: list):
    """Side-by-side frames (height, 2 * width + 2, 3) of two panel sequences (a 2-pixel divider)."""
    n = min(len(left), len(right))
    if n == 0:
        raise ConvSynthError("nothing to render: an empty panel sequence")
    gap = np.full((left[0].shape[0], 2, 3), 60, np.uint8)
    for i in range(n):
        yield np.ascontiguousarray(np.concatenate([left[i], gap, right[i]], axis=1))


def side_by_side_frames(left, right, width: int, height: int, step: int = 1, yaw_deg: float = 35.0, pitch_deg: float = 12.0):
    """Frames (height, 2 * width + 2 gap, 3) uint8 of the ``left`` and ``right`` bodies (one camera
    for both panels, fitted to all bodies), every ``step``-th frame."""
    if not left or not right:
        raise ConvSynthError("a study video needs bodies in both panels")
    r = PanelRenderer([left, right], width, height, step, yaw_deg, pitch_deg)
    yield from join_panels(r.frames(left), r.frames(right))


def render_pair_video(left, right, fps: float, path: str | Path, audio: str | Path | None = None, width: int = 320,
                      height: int = 360, render_fps: float = 15.0, yaw_deg: float = 35.0, pitch_deg: float = 12.0) -> Path:
    """Write ``path`` (MP4, H.264 yuv420p + AAC when ``audio`` is a WAV), the ``left`` and ``right``
    bodies (motion at ``fps``) side by side, drawn at about ``render_fps``. Written atomically."""
    if width % 2 or height % 2:
        raise ConvSynthError(f"study video panels need an even width and height, got {width} x {height}")
    step = _step(fps, render_fps)
    return write_video(side_by_side_frames(left, right, width, height, step, yaw_deg, pitch_deg), fps / step, path, audio)
