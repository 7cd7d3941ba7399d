"""Stick-figure rendering of motion: side-by-side panels (e.g. synthesized | ground truth) with both
characters in their chairs, the audio labels as a timeline underneath and synthetic transitions
marked, written as an animated GIF (matplotlib's PillowWriter; no external binaries) or MP4 (when
ffmpeg is on the PATH), plus a contact-sheet PNG of evenly spaced frames.

Positions come from the project's forward kinematics (:func:`convsynth_jax.kinematics.forward_kinematics`)
and are drawn in an orthographic view: vertical = the up axis (+Y), horizontal = the ground axis
along which the drawn roots spread the most (the axis joining two seated characters; X for one).
Matplotlib is used through its object-oriented API only (no pyplot state, no backend switching).

Speed: frames are subsampled to ``render_fps`` (default 10 fps: a 15 s window is 150 frames), every
body is one LineCollection whose segments are replaced per frame, and GIF frames are blitted (the
static axes and timeline drawn once) and mapped onto one palette.
"""
from __future__ import annotations

import logging
import shutil
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure

from .errors import ConvSynthError, MissingFileError
from .figures.save import save_figure
from .utils import atomic_path

log = logging.getLogger(__name__)

LABEL_COLORS = {"PC": "#4f6fa8", "LR": "#3d9a5b", "HP": "#d9a441", "PH": "#d9a441", "idle": "#dddddd"}
BODY_COLORS = ("#1f3b73", "#8c2d19", "#2f6f3e", "#6b3d8c")
TRANSITION_COLOR = "#e0301e"
TRANSITION_HALO = 3      # frames either side of a synthetic transition drawn in TRANSITION_COLOR


@dataclass(frozen=True)
class Track:
    """One body in a panel. positions: (frames, joints, 3) world positions (Y up); parents: (joints,)
    parent index (-1 root); transitions: output frames that start a synthetic transition."""

    name: str
    positions: np.ndarray
    parents: tuple[int, ...]
    transitions: tuple[int, ...] = ()


@dataclass(frozen=True)
class Panel:
    """One view (e.g. "synthesized" or "ground truth") holding the bodies drawn together."""

    title: str
    tracks: tuple[Track, ...]


@dataclass(frozen=True)
class Timeline:
    """Audio labels of one speaker: segments with columns kind, start, end (seconds, window-relative)."""

    name: str
    segments: pd.DataFrame = field(default_factory=lambda: pd.DataFrame(columns=["kind", "start", "end"]))


def track_from_motion(motion, name: str, transitions=()) -> Track:
    """A Track from a :class:`~convsynth_jax.skeleton.Motion` (forward kinematics here)."""
    from .kinematics import forward_kinematics

    pos = np.asarray(forward_kinematics(motion), dtype=np.float32)
    return Track(name, pos, tuple(int(p) for p in motion.skeleton.parents), tuple(int(t) for t in transitions))


def _num_frames(panels) -> int:
    return min(t.positions.shape[0] for p in panels for t in p.tracks)


def _axes_of(panels) -> int:
    """The ground axis (0 = X, 2 = Z) along which the roots of all bodies spread the most."""
    roots = np.concatenate([t.positions[:, 0, :] for p in panels for t in p.tracks])
    spread = roots.max(0) - roots.min(0)
    return 2 if spread[2] > spread[0] else 0


def _limits(panels, h: int):
    pts = np.concatenate([t.positions[..., [h, 1]].reshape(-1, 2) for p in panels for t in p.tracks])
    lo, hi = np.nanmin(pts, 0), np.nanmax(pts, 0)
    pad = 0.08 * float(max(hi - lo)) + 1e-6
    return (lo[0] - pad, hi[0] + pad), (lo[1] - pad, hi[1] + pad)


def _segments(track: Track, f: int, h: int) -> np.ndarray:
    p = track.positions[f][:, [h, 1]]
    bones = [(j, q) for j, q in enumerate(track.parents) if q >= 0]
    return np.stack([[p[q], p[j]] for j, q in bones]) if bones else np.zeros((0, 2, 2))


def _near_transition(track: Track, f: int) -> bool:
    return any(abs(f - t) <= TRANSITION_HALO for t in track.transitions)


class _Scene:
    """The figure: one axis per panel above a timeline axis; ``draw(f)`` poses every body at frame f."""

    def __init__(self, panels, timelines, fps: float, width: float = 4.0, dpi: int = 80, clock: bool = True,
                 ground_axis: int | None = None):
        if not panels or not all(p.tracks for p in panels):
            raise ConvSynthError("nothing to render: every panel needs at least one body")
        if ground_axis not in (None, 0, 2):
            raise ConvSynthError(f"ground_axis must be 0 (X), 2 (Z) or None (chosen from the roots), got {ground_axis!r}")
        self.panels, self.fps, self.clock = list(panels), float(fps), clock
        self.n = _num_frames(self.panels)
        self.h = _axes_of(self.panels) if ground_axis is None else ground_axis
        xlim, ylim = _limits(self.panels, self.h)
        aspect = (ylim[1] - ylim[0]) / max(xlim[1] - xlim[0], 1e-6)
        rows = max(1, len(timelines)) + sum(bool(t.transitions) for p in panels[:1] for t in p.tracks)
        self.fig = Figure(figsize=(width * len(self.panels), width * min(aspect, 1.4) + 0.28 * rows + 0.6), dpi=dpi)
        gs = self.fig.add_gridspec(2, len(self.panels), height_ratios=[width * min(aspect, 1.4), 0.28 * rows + 0.25],
                                   hspace=0.25, wspace=0.05, left=0.13, right=0.98, top=0.93, bottom=0.08)
        self.lines, self.axes = [], []
        for i, p in enumerate(self.panels):
            ax = self.fig.add_subplot(gs[0, i])
            self.axes.append(ax)
            ax.set_xlim(*xlim)
            ax.set_ylim(*ylim)
            ax.set_aspect("equal")
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_title(p.title, fontsize=9)
            for k, t in enumerate(p.tracks):
                lc = LineCollection(_segments(t, 0, self.h), colors=BODY_COLORS[k % len(BODY_COLORS)], linewidths=2)
                ax.add_collection(lc)
                self.lines.append((t, lc, BODY_COLORS[k % len(BODY_COLORS)]))
        self.time_text = self.fig.text(0.5, 0.975, "", ha="center", va="top", fontsize=8)
        self.tl = self.fig.add_subplot(gs[1, :])
        self._timeline(timelines)
        self.cursor = self.tl.axvline(0.0, color="k", lw=1)

    def _timeline(self, timelines):
        ax, dur = self.tl, self.n / self.fps
        rows = [(tl.name, tl.segments) for tl in timelines]
        marks = [(t.name, t.transitions) for t in self.panels[0].tracks if t.transitions]
        labels = []
        for i, (name, seg) in enumerate(rows):
            for r in seg.itertuples():
                s, e = max(float(r.start), 0.0), min(float(r.end), dur)
                if e > s:
                    ax.broken_barh([(s, e - s)], (i - 0.4, 0.8), color=LABEL_COLORS.get(str(r.kind), "#999999"))
                    ax.text(s, i, str(r.kind), fontsize=5, va="center", color="w")
            labels.append(name)
        for j, (name, tr) in enumerate(marks):
            y = len(rows) + j
            ax.vlines(np.asarray(tr) / self.fps, y - 0.4, y + 0.4, color=TRANSITION_COLOR, lw=1)
            labels.append(f"{name}: transitions")
        ax.set_yticks(range(len(labels)), labels, fontsize=6)
        ax.set_ylim(-0.6, max(len(labels), 1) - 0.4)
        ax.set_xlim(0, dur)
        ax.tick_params(axis="x", labelsize=6)
        ax.set_xlabel("time (s)", fontsize=7)

    def draw(self, f: int):
        for t, lc, color in self.lines:
            lc.set_segments(_segments(t, f, self.h))
            lc.set_color(TRANSITION_COLOR if _near_transition(t, f) else color)
        self.cursor.set_xdata([f / self.fps, f / self.fps])
        if not self.clock:   # text is the costliest artist to draw; the cursor shows the time
            return [lc for _, lc, _ in self.lines] + [self.cursor]
        self.time_text.set_text(f"frame {f}  t = {f / self.fps:.2f} s")
        return [lc for _, lc, _ in self.lines] + [self.cursor, self.time_text]


def _gif_frames(scene: "_Scene", frames) -> list:
    """Draw ``frames`` by blitting: the static parts (axes, timeline) are rendered once, then per
    frame only the bodies, the cursor and the clock (Agg canvas; no pyplot)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from PIL import Image

    canvas = FigureCanvasAgg(scene.fig)
    dynamic = scene.draw(frames[0])
    for a in dynamic:
        a.set_animated(True)
    canvas.draw()
    background = canvas.copy_from_bbox(scene.fig.bbox)
    images, palette = [], None
    for f in frames:
        canvas.restore_region(background)
        for a in scene.draw(f):
            a.axes.draw_artist(a) if a.axes is not None else scene.fig.draw_artist(a)
        rgb = np.asarray(canvas.buffer_rgba())[..., :3]
        if palette is None:  # one palette for all frames: the first frame plus every colour a body can take
            from matplotlib.colors import to_rgb

            swatch = np.array([[int(255 * c) for c in to_rgb(x)] for x in (*BODY_COLORS, TRANSITION_COLOR)], np.uint8)
            strip = np.repeat(swatch[None], 8, axis=0).repeat(8, axis=1)
            pad = np.full((strip.shape[0], rgb.shape[1], 3), 255, np.uint8)
            pad[:, :strip.shape[1]] = strip[:, :rgb.shape[1]]
            palette = Image.fromarray(np.concatenate([rgb, pad])).quantize(colors=96, method=Image.Quantize.MEDIANCUT)
        images.append(Image.fromarray(rgb.copy()).quantize(palette=palette, dither=Image.Dither.NONE))
    return images


def render_animation(panels, timelines, fps: float, path: str | Path, render_fps: float = 10.0, dpi: int = 80,
                     width: float = 3.2) -> Path:
    """Animate ``panels`` to ``path``: ``.gif`` (frames blitted on an Agg canvas and written with
    Pillow, matplotlib's own image dependency) or ``.mp4`` (matplotlib's FFMpegWriter; when ffmpeg
    is not installed, a GIF is written beside it instead and its path returned). Every
    ``round(fps / render_fps)``-th frame is drawn."""
    path = Path(path)
    scene = _Scene(panels, timelines, fps, width=width, dpi=dpi)
    step = max(1, int(round(fps / render_fps)))
    frames = list(range(0, scene.n, step))
    out_fps = fps / step
    if path.suffix.lower() == ".mp4" and shutil.which("ffmpeg") is None:
        log.warning("ffmpeg not found: writing a GIF instead of %s", path)
        path = path.with_suffix(".gif")
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.suffix.lower() == ".mp4":
        from matplotlib.animation import FFMpegWriter, FuncAnimation

        anim = FuncAnimation(scene.fig, scene.draw, frames=frames, blit=False)
        with atomic_path(path) as tmp:
            anim.save(str(tmp), writer=FFMpegWriter(fps=out_fps), dpi=dpi)
        return path
    images = _gif_frames(scene, frames)
    with atomic_path(path) as tmp:
        images[0].save(tmp, format="GIF", save_all=True, append_images=images[1:], loop=0,
                       duration=int(round(1000 / out_fps)))
    return path


def _rgb_frames(scene: "_Scene", frames):
    """RGB arrays (H, W, 3) of ``frames``, blitted like :func:`_gif_frames` (no palette), with even
    height and width (H.264's 4:2:0 needs them; the last row / column is repeated)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = FigureCanvasAgg(scene.fig)
    for a in scene.draw(frames[0]):
        a.set_animated(True)
    canvas.draw()
    background = canvas.copy_from_bbox(scene.fig.bbox)
    for f in frames:
        canvas.restore_region(background)
        for a in scene.draw(f):
            a.axes.draw_artist(a) if a.axes is not None else scene.fig.draw_artist(a)
        rgb = np.asarray(canvas.buffer_rgba())[..., :3]
        h, w = rgb.shape[0] + rgb.shape[0] % 2, rgb.shape[1] + rgb.shape[1] % 2
        yield np.ascontiguousarray(np.pad(rgb, ((0, h - rgb.shape[0]), (0, w - rgb.shape[1]), (0, 0)), mode="edge"))


def _raster_frames(scene: "_Scene", frames):
    """What :func:`_rgb_frames` draws, rasterized with NumPy instead of matplotlib (about 20 times
    faster): the static figure (axes, titles, timeline) is drawn once by matplotlib without the
    bodies and the cursor; per frame every bone is stamped onto a copy as a 2-pixel line (no
    anti-aliasing) in its body's colour (red near a synthetic transition), and the cursor as a
    1-pixel column of the timeline. Even height and width as :func:`_rgb_frames`."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.colors import to_rgb

    canvas = FigureCanvasAgg(scene.fig)
    for _, lc, _ in scene.lines:
        lc.set_visible(False)
    scene.cursor.set_visible(False)
    scene.time_text.set_visible(False)
    canvas.draw()
    bg = np.asarray(canvas.buffer_rgba())[..., :3].copy()
    for _, lc, _ in scene.lines:
        lc.set_visible(True)
    scene.cursor.set_visible(True)
    scene.time_text.set_visible(scene.clock)
    H, W = bg.shape[:2]
    h2, w2 = H + H % 2, W + W % 2
    bg = np.pad(bg, ((0, h2 - H), (0, w2 - W), (0, 0)), mode="edge")
    samples = np.linspace(0.0, 1.0, 48)[None, :, None]
    bodies = []   # (track, pixel positions (F, J, 2) as (row, col), bone pairs, colour, clip box)
    k = 0
    for ax, p in zip(scene.axes, scene.panels):
        x0, y0, x1, y1 = ax.bbox.extents
        box = (int(np.ceil(H - y1)), int(np.floor(H - y0)), int(np.ceil(x0)), int(np.floor(x1)))
        for t in p.tracks:
            xy = t.positions[..., [scene.h, 1]].astype(np.float64)
            disp = ax.transData.transform(xy.reshape(-1, 2)).reshape(xy.shape)
            rc = np.stack([H - disp[..., 1], disp[..., 0]], axis=-1)
            bones = np.array([(q, j) for j, q in enumerate(t.parents) if q >= 0], np.int64).reshape(-1, 2)
            color = np.array([int(255 * c) for c in to_rgb(BODY_COLORS[k % len(BODY_COLORS)])], np.uint8)
            bodies.append((t, rc, bones, color, box))
            k += 1
    red = np.array([int(255 * c) for c in to_rgb(TRANSITION_COLOR)], np.uint8)
    tx0, ty0, tx1, ty1 = scene.tl.bbox.extents
    rows = slice(int(np.ceil(H - ty1)), int(np.floor(H - ty0)))
    for f in frames:
        img = bg.copy()
        for t, rc, bones, color, (r0, r1, c0, c1) in bodies:
            a, b = rc[f, bones[:, 0]], rc[f, bones[:, 1]]
            pts = (a[:, None, :] + (b - a)[:, None, :] * samples).reshape(-1, 2)
            r, c = np.floor(pts[:, 0]).astype(np.int64), np.floor(pts[:, 1]).astype(np.int64)
            col = red if _near_transition(t, f) else color
            for dr in (0, 1):
                for dc in (0, 1):
                    rr, cc = r + dr, c + dc
                    ok = (rr >= r0) & (rr < r1) & (cc >= c0) & (cc < c1)
                    img[rr[ok], cc[ok]] = col
        x = scene.tl.transData.transform((f / scene.fps, 0.0))[0]
        if tx0 <= x < tx1:
            img[rows, int(x)] = 0
        yield img


def ffmpeg_exe() -> str:
    """The ffmpeg binary that the ``imageio-ffmpeg`` package ships (a project dependency)."""
    try:
        import imageio_ffmpeg
    except ImportError as e:  # pragma: no cover - a dependency of the package
        raise ConvSynthError("video output needs the imageio-ffmpeg package (pip install imageio-ffmpeg)") from e
    return imageio_ffmpeg.get_ffmpeg_exe()


def render_video(panels, timelines, fps: float, path: str | Path, audio: str | Path | None = None,
                 render_fps: float = 10.0, dpi: int = 80, width: float = 3.2, clock: bool = False,
                 ground_axis: int | None = None) -> Path:
    """An H.264 MP4 of ``panels`` (every ``round(fps / render_fps)``-th frame, blitted on an Agg canvas
    and piped to the ffmpeg binary of ``imageio-ffmpeg``, so no system ffmpeg is needed), with the WAV
    ``audio`` (if given) muxed in as an AAC track starting at frame 0. ``clock``: draw the frame number
    and time above the panels (off by default: about 4 ms a frame; the timeline's cursor shows the time;
    on, frames are drawn by matplotlib, :func:`_rgb_frames`; off, by :func:`_raster_frames`).
    ``ground_axis``: the horizontal axis of the view, 0 = X or 2 = Z (None: the axis along which the
    roots spread the most, :func:`_axes_of`)."""
    path = Path(path)
    scene = _Scene(panels, timelines, fps, width=width, dpi=dpi, clock=clock, ground_axis=ground_axis)
    step = max(1, int(round(fps / render_fps)))
    frames = list(range(0, scene.n, step))
    gen = (_rgb_frames if clock else _raster_frames)(scene, frames)
    first = next(gen)
    return write_mp4(path, first, gen, fps / step, audio, macro_block_size=1)


def write_mp4(path: Path, first, rest, fps: float, audio: str | Path | None = None, **writer_options) -> Path:
    """Write the RGB frames ``first`` and then ``rest`` to the MP4 ``path`` (atomically: a temporary file
    renamed into place), with the WAV ``audio`` muxed in as AAC when given. ``writer_options``: further
    keyword arguments of ``imageio_ffmpeg.write_frames`` (codec, pixel format, block size)."""
    import imageio_ffmpeg

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path, suffix=".mp4") as tmp:
        w = imageio_ffmpeg.write_frames(str(tmp), (first.shape[1], first.shape[0]), fps=fps,
                                        audio_path=None if audio is None else str(audio),
                                        audio_codec=None if audio is None else "aac", ffmpeg_log_level="error",
                                        **writer_options)
        w.send(None)
        w.send(first)
        for img in rest:
            w.send(img)
        w.close()
    return path


def probe_streams(path: str | Path) -> dict:
    """{"video": n, "audio": n, "duration": seconds or None}: the streams ffmpeg finds in a media file
    (read from ``ffmpeg -i``'s report, with the ffmpeg binary of ``imageio-ffmpeg``)."""
    import re
    import subprocess

    p = Path(path)
    if not p.is_file():
        raise MissingFileError("no such media file", p)
    err = subprocess.run([ffmpeg_exe(), "-hide_banner", "-i", str(p)], capture_output=True, text=True).stderr
    d = re.search(r"Duration: (\d+):(\d+):([\d.]+)", err)
    dur = None if d is None else 3600 * int(d.group(1)) + 60 * int(d.group(2)) + float(d.group(3))
    return {"video": len(re.findall(r"Stream #\S+.*: Video:", err)), "audio": len(re.findall(r"Stream #\S+.*: Audio:", err)),
            "duration": dur}


def contact_sheet(panels, timelines, fps: float, path: str | Path, num: int = 6, dpi: int = 90,
                  width: float = 2.2) -> Path:
    """A PNG grid: one row per panel, ``num`` evenly spaced frames per row (times in the titles;
    bodies within 3 frames of a synthetic transition in red), with the label timeline underneath."""
    panels = list(panels)
    if not panels or not all(p.tracks for p in panels):
        raise ConvSynthError("nothing to render: every panel needs at least one body")
    n = _num_frames(panels)
    h = _axes_of(panels)
    xlim, ylim = _limits(panels, h)
    aspect = (ylim[1] - ylim[0]) / max(xlim[1] - xlim[0], 1e-6)
    frames = np.unique(np.linspace(0, n - 1, num).round().astype(int))
    cell = width * min(aspect, 1.4)
    fig = Figure(figsize=(width * len(frames), cell * len(panels) + 1.1), dpi=dpi)
    gs = fig.add_gridspec(len(panels) + 1, len(frames), height_ratios=[cell] * len(panels) + [0.9],
                          hspace=0.35, wspace=0.03, left=0.08, right=0.99, top=0.95, bottom=0.07)
    for i, p in enumerate(panels):
        for c, f in enumerate(frames):
            ax = fig.add_subplot(gs[i, c])
            ax.set_xlim(*xlim)
            ax.set_ylim(*ylim)
            ax.set_aspect("equal")
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_title(f"{f / fps:.1f} s", fontsize=7)
            if c == 0:
                ax.set_ylabel(p.title, fontsize=8)
            for k, t in enumerate(p.tracks):
                color = TRANSITION_COLOR if _near_transition(t, f) else BODY_COLORS[k % len(BODY_COLORS)]
                ax.add_collection(LineCollection(_segments(t, int(f), h), colors=color, linewidths=1.5))
    tl = fig.add_subplot(gs[len(panels), :])
    dur = n / fps
    names = []
    for i, line in enumerate(timelines):
        for r in line.segments.itertuples():
            s, e = max(float(r.start), 0.0), min(float(r.end), dur)
            if e > s:
                tl.broken_barh([(s, e - s)], (i - 0.4, 0.8), color=LABEL_COLORS.get(str(r.kind), "#999999"))
        names.append(line.name)
    for t in panels[0].tracks:
        if t.transitions:
            y = len(names)
            tl.vlines(np.asarray(t.transitions) / fps, y - 0.4, y + 0.4, color=TRANSITION_COLOR, lw=1)
            names.append(f"{t.name}: transitions")
    tl.vlines(frames / fps, -0.5, max(len(names), 1) - 0.5, color="k", lw=0.5, ls=":")
    tl.set_yticks(range(len(names)), names, fontsize=6)
    tl.set_ylim(-0.6, max(len(names), 1) - 0.4)
    tl.set_xlim(0, dur)
    tl.tick_params(axis="x", labelsize=6)
    tl.set_xlabel("time (s)", fontsize=7)
    return save_figure(fig, path, dpi=dpi)


def bvh_files(path: str | Path) -> list[Path]:
    """The BVH file ``path`` or the ``*.bvh`` files directly in the folder ``path`` (sorted).
    Raises MissingFileError for a missing path or a folder without BVH files."""
    p = Path(path)
    if not p.exists():
        raise MissingFileError("no such BVH file or folder", p)
    if p.is_dir():
        files = sorted(q for q in p.iterdir() if q.suffix.lower() == ".bvh" and q.is_file())
        if not files:
            raise MissingFileError("folder holds no .bvh files", p)
        return files
    if p.suffix.lower() != ".bvh":
        raise MissingFileError("not a .bvh file", p)
    return [p]
