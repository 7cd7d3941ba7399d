"""Task ``render``: ``convsynth task=render path=FILE.bvh|DIR`` draws BVH motion (ours or anyone's)
with :mod:`convsynth_jax.render` (the renderer of every video of the project): an animation
(``render.gif``, or ``render.mp4`` with ``task.format=mp4``) and a contact sheet
(``contact_sheet.png``).

An output folder of ``task=synthesize`` or ``task=converse`` (it holds ``report.json``) is drawn as one
scene with both characters in their chairs, over a timeline of each character's audio labels (the
report's ``segments``) with its synthetic transitions as ticks; the MP4 of a converse folder carries
its ``conversation.wav``. Any other folder is drawn one panel per file (at most ``task.max_files``,
sorted by name), each seen from the front. ``task.start`` / ``task.duration`` (seconds) select the
frames. Files are resampled to the first file's frame rate.
"""
from __future__ import annotations

import json
import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import pandas as pd

from ..errors import ConfigError, FormatError

log = logging.getLogger(__name__)


def _report(folder: Path) -> tuple[dict, dict]:
    """(character -> synthetic transition frames, character -> label rows) from the report.json of a
    task=synthesize or task=converse output folder (empty without one)."""
    rep = folder / "report.json"
    if not rep.is_file():
        return {}, {}
    try:
        data = json.loads(rep.read_text())
        chars = data.get("characters", {})
        trans = {c: [int(t["frame"]) for t in (v.get("transitions") or [])] for c, v in chars.items() if isinstance(v, dict)}
        segs = data.get("segments") or {}
        labels = {c: [(str(r["kind"]), float(r["start"]), float(r["end"])) for r in rows]
                  for c, rows in segs.items() if isinstance(rows, list)}
    except (json.JSONDecodeError, UnicodeDecodeError, AttributeError, KeyError, TypeError, ValueError) as e:
        raise FormatError(f"not a task=synthesize or task=converse report ({type(e).__name__}: {e})", rep) from None
    return trans, labels


@dataclass(frozen=True)
class RenderSettings:
    """``conf/task/render.yaml`` (the file or folder: top-level ``path``)."""

    name: str = "render"
    format: str = "gif"                 # gif | mp4 (H.264 through imageio-ffmpeg's own ffmpeg)
    start: float = 0.0                  # seconds
    duration: Optional[float] = 15.0    # seconds from start; None = to the end
    render_fps: float = 10.0            # frames drawn per second of motion
    max_files: int = 4                  # at most this many BVH files of a folder (sorted by name)
    contact_frames: int = 6


def run(cfg, out_dir: Path) -> dict:
    from ..io import load_bvh
    from ..io.bvh import bvh_files
    from ..render import Panel, Timeline, body_from_motion, contact_sheet, render_animation, render_video

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
    fmt = task.format.lower()
    if fmt not in ("gif", "mp4"):
        raise ConfigError(f"task.format={fmt!r}: expected gif or mp4")
    first = load_bvh(files[0])
    motions = [first] + [load_bvh(f, fps=first.fps) for f in files[1:]]
    fps = float(first.fps)
    n = min(m.num_frames for m in motions)
    f0 = int(round(task.start * fps))
    dur = task.duration
    f1 = n if dur is None else min(n, f0 + int(round(float(dur) * fps)))
    if not 0 <= f0 < f1:
        raise ConfigError(f"task.start={task.start} s is outside the motion ({n / fps:.2f} s in {src})")
    scene = src.is_dir() and (src / "report.json").is_file()
    trans, labels = _report(src) if scene else ({}, {})
    bodies, timelines, ticks = [], [], {}
    t0, t1 = f0 / fps, f1 / fps
    for k, (f, m) in enumerate(zip(files, motions)):
        bodies.append(body_from_motion(m.slice(f0, f1), f.stem, k))
        ticks[f.stem] = [x - f0 for x in trans.get(f.stem, []) if f0 <= x < f1]
        if scene:
            rows = [(kind, s - t0, e - t0) for kind, s, e in labels.get(f.stem, []) if e > t0 and s < t1]
            timelines.append(Timeline(f.stem, pd.DataFrame(rows, columns=["kind", "start", "end"]),
                                      tuple(x / fps for x in ticks[f.stem]), k))
    panels = [Panel(src.name, tuple(bodies))] if scene else [Panel(b.name, (b,)) for b in bodies]
    if fmt == "mp4":
        wav = src / "conversation.wav" if scene and (src / "conversation.wav").is_file() else None
        if wav is not None and f0 > 0:
            log.info("task.start > 0: the MP4 is written without %s (it starts at 0 s)", wav.name)
            wav = None
        anim = render_video(panels, timelines, fps, out_dir / "render.mp4", audio=wav, render_fps=task.render_fps)
    else:
        anim = render_animation(panels, timelines, fps, out_dir / "render.gif", render_fps=task.render_fps)
    sheet = contact_sheet(panels, timelines, fps, out_dir / "contact_sheet.png", num=task.contact_frames)
    log.info("rendered %d file(s) from %s to %s and %s", len(files), src, anim, sheet)
    return {"path": str(src), "files": [str(f) for f in files], "frames": [f0, f1], "fps": fps,
            "animation": anim.name, "contact_sheet": sheet.name,
            "transitions": {k: v for k, v in ticks.items() if v}}
