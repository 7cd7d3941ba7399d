"""Task ``render``: ``convsynth task=render path=FILE.bvh|DIR`` draws BVH motion (ours or anyone's)
as a stick-figure animation (``render.gif``, or ``render.mp4`` with ``task.format=mp4`` when ffmpeg
is installed) and a contact sheet (``contact_sheet.png``) with :mod:`convsynth_jax.render`.

A folder written by ``task=synthesize`` (it holds ``report.json``) is drawn as one scene with both
characters in their chairs and each character's synthetic transitions (from ``report.json``)
marked; any other folder is drawn one panel per file (at most ``task.max_files``, sorted by name).
``task.start`` / ``task.duration`` (seconds) select the frames. Files are resampled to the first
file's frame rate.
"""
from __future__ import annotations

import json
import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

from ..errors import ConfigError, FormatError

log = logging.getLogger(__name__)


def _transitions(folder: Path) -> dict:
    """character -> synthetic transition frames from a task=synthesize report.json (empty if none)."""
    rep = folder / "report.json"
    if not rep.is_file():
        return {}
    try:
        chars = json.loads(rep.read_text()).get("characters", {})
    except (json.JSONDecodeError, UnicodeDecodeError, AttributeError) as e:
        raise FormatError(f"not a task=synthesize report ({e})", rep) from None
    return {c: [int(t["frame"]) for t in (v.get("transitions") or [])] for c, v in chars.items()
            if isinstance(v, dict)}


@dataclass(frozen=True)
class RenderSettings:
    """``conf/task/render.yaml`` (the file or folder: top-level ``path``)."""

    name: str = "render"
    format: str = "gif"                 # gif | mp4 (needs ffmpeg; falls back to gif)
    start: float = 0.0                  # seconds
    duration: Optional[float] = 15.0    # seconds from start; None = to the end
    render_fps: float = 10.0            # frames drawn per second of motion
    max_files: int = 4                  # at most this many BVH files of a folder (sorted by name)
    contact_frames: int = 6


def run(cfg, out_dir: Path) -> dict:
    from ..io import load_bvh
    from ..render import Panel, bvh_files, contact_sheet, render_animation, track_from_motion

    from ..config import task_settings

    task = task_settings(cfg)
    if not cfg.get("path"):
        raise ConfigError("task=render needs path=FILE.bvh or path=DIR")
    src = Path(str(cfg.path))
    files = bvh_files(src)
    max_files = task.max_files
    if len(files) > max_files:
        log.warning("%s holds %d BVH files; rendering the first %d (task.max_files)", src, len(files), max_files)
        files = files[:max_files]
    first = load_bvh(files[0])
    motions = [first] + [load_bvh(f, fps=first.fps) for f in files[1:]]
    fps = float(first.fps)
    n = min(m.num_frames for m in motions)
    f0 = int(round(task.start * fps))
    dur = task.duration
    f1 = n if dur is None else min(n, f0 + int(round(float(dur) * fps)))
    if not 0 <= f0 < f1:
        raise ConfigError(f"task.start={task.start} s is outside the motion ({n / fps:.2f} s in {src})")
    trans = _transitions(src) if src.is_dir() else {}
    tracks = []
    for f, m in zip(files, motions):
        t = [x - f0 for x in trans.get(f.stem, []) if f0 <= x < f1]
        tracks.append(track_from_motion(m.slice(f0, f1), f.stem, t))
    if src.is_dir() and (src / "report.json").is_file():
        panels = [Panel(src.name, tuple(tracks))]
    else:
        panels = [Panel(t.name, (t,)) for t in tracks]
    fmt = task.format.lower()
    if fmt not in ("gif", "mp4"):
        raise ConfigError(f"task.format={fmt!r}: expected gif or mp4")
    anim = render_animation(panels, [], fps, out_dir / f"render.{fmt}", render_fps=task.render_fps)
    sheet = contact_sheet(panels, [], fps, out_dir / "contact_sheet.png", num=task.contact_frames)
    log.info("rendered %d file(s) from %s to %s and %s", len(files), src, anim, sheet)
    return {"path": str(src), "files": [str(f) for f in files], "frames": [f0, f1], "fps": fps,
            "animation": anim.name, "contact_sheet": sheet.name,
            "transitions": {t.name: list(t.transitions) for t in tracks if t.transitions}}
