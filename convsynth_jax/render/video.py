"""Files: MP4 through the ffmpeg binary of ``imageio-ffmpeg`` (WAV muxed in as AAC), GIF animations and
contact sheets, all written atomically."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import ConvSynthError, MissingFileError
from ..utils import atomic_path
from .frames import FrameRenderer
from .raster import PanelRenderer
from .style import BODY_RGB, CURSOR_RGB, LABEL_RGB, NOSE_RGB, PAGE_RGB, SKIN_RGB, TEXT_RGB, TICK_RGB
from .text import _fit, _font, _text_width
from .timeline import TimelineStrip


def ffmpeg_exe() -> str:
    """The ffmpeg binary that the ``imageio-ffmpeg`` package ships (a project dependency)."""
    try:
        import imageio_ffmpeg
    except ImportError as e:  # pragma: no cover - a dependency of the package
        raise ConvSynthError("video output needs the imageio-ffmpeg package (pip install imageio-ffmpeg)") from e
    return imageio_ffmpeg.get_ffmpeg_exe()


def write_mp4(path: Path, first, rest, fps: float, audio: str | Path | None = None, **writer_options) -> Path:
    """Write the RGB frames ``first`` and then ``rest`` to the MP4 ``path`` (atomically: a temporary file
    renamed into place), with the WAV ``audio`` muxed in as AAC when given. ``writer_options``: further
    keyword arguments of ``imageio_ffmpeg.write_frames`` (codec, pixel format, block size)."""
    import os

    import imageio_ffmpeg

    # imageio-ffmpeg starts ffmpeg with preexec_fn=os.setpgrp (to keep Ctrl-C from it), which makes
    # Python run the at-fork hooks: JAX's warns "os.fork() was called ... deadlock" on every video.
    # Without it ffmpeg starts without a fork hook in this process (and a Ctrl-C stops it too).
    os.environ.setdefault("IMAGEIO_FFMPEG_NO_PREVENT_SIGINT", "1")
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


def write_video(frames, fps: float, path: str | Path, audio: str | Path | None = None) -> Path:
    """Write ``frames`` (an iterable of uint8 (H, W, 3), even H and W) to ``path``: MP4, H.264 yuv420p
    with ``+faststart``, plus the WAV ``audio`` as AAC when given. Written atomically. Encoding
    settings are chosen for speed: x264 ``superfast`` and ffmpeg's ``fast`` AAC coder take 3.2-3.8 s
    of ffmpeg CPU for a minute of 640 x 484 at 10 fps against 5.2-5.3 s with ``veryfast`` and the
    default coder (docs/render.md); the files are larger, 2.2 MB per minute."""
    path = Path(path)
    gen = iter(frames)
    first = next(gen)
    if first.shape[0] % 2 or first.shape[1] % 2:
        raise ConvSynthError(f"H.264 frames need an even width and height, got {first.shape[1]} x {first.shape[0]}", path)
    return write_mp4(path, first, gen, fps, audio, macro_block_size=2, codec="libx264", pix_fmt_out="yuv420p",
                     output_params=["-preset", "superfast", *(["-aac_coder", "fast"] if audio is not None else []),
                                    "-movflags", "+faststart"])


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


def _step(fps: float, render_fps: float) -> int:
    if not render_fps or render_fps <= 0:
        raise ConvSynthError(f"the frames drawn per second must be positive, got {render_fps}")
    return max(1, int(round(float(fps) / float(render_fps))))


def render_video(panels, timelines, fps: float, path: str | Path, audio: str | Path | None = None,
                 render_fps: float = 10.0, panel_width: int = 480, panel_height: int = 360,
                 timeline_span_s: float | None = 15.0, clock: bool = True, yaw_deg: float = 35.0,
                 pitch_deg: float = 12.0, across=None) -> Path:
    """An H.264 MP4 of ``panels`` over the ``timelines`` (every ``round(fps / render_fps)``-th motion
    frame, :class:`FrameRenderer`), with the WAV ``audio`` (if given) muxed in as AAC from frame 0.
    ``across``: see :func:`three_quarter_camera`."""
    r = FrameRenderer(panels, timelines, fps, panel_width, panel_height, timeline_span_s, yaw_deg, pitch_deg, clock,
                      across=across)
    step = _step(fps, render_fps)
    return write_video(r.frames(step), fps / step, path, audio)


def render_animation(panels, timelines, fps: float, path: str | Path, render_fps: float = 10.0,
                     panel_width: int = 320, panel_height: int = 260, timeline_span_s: float | None = None,
                     clock: bool = True) -> Path:
    """Animate ``panels`` over ``timelines`` to ``path``: ``.gif`` (frames mapped onto one palette,
    written with Pillow) or ``.mp4`` (:func:`render_video`, no audio). Every
    ``round(fps / render_fps)``-th frame is drawn."""
    path = Path(path)
    step = _step(fps, render_fps)
    if path.suffix.lower() == ".mp4":
        return render_video(panels, timelines, fps, path, None, render_fps, panel_width, panel_height, timeline_span_s, clock)
    if path.suffix.lower() != ".gif":
        raise ConvSynthError(f"an animation is a .gif or an .mp4, not {path.suffix or 'a file without suffix'}", path)
    from PIL import Image

    r = FrameRenderer(panels, timelines, fps, panel_width, panel_height, timeline_span_s, clock=clock)
    palette, images = None, []
    for img in r.frames(step):
        if palette is None:   # one palette: the first frame plus every body, label and tick colour
            swatch = np.array([*BODY_RGB, SKIN_RGB, NOSE_RGB, *LABEL_RGB.values(), TICK_RGB, CURSOR_RGB], np.uint8)
            strip = np.zeros((8, img.shape[1], 3), np.uint8) + 255
            cells = np.repeat(swatch, 8, axis=0)[: img.shape[1]]
            strip[:, :len(cells)] = cells[None]
            palette = Image.fromarray(np.concatenate([img, strip])).quantize(colors=128, method=Image.Quantize.MEDIANCUT)
        images.append(Image.fromarray(img).quantize(palette=palette, dither=Image.Dither.NONE))
    with atomic_path(path) as tmp:
        images[0].save(tmp, format="GIF", save_all=True, append_images=images[1:], loop=0,
                       duration=int(round(1000 * step / fps)))
    return path


def contact_sheet(panels, timelines, fps: float, path: str | Path, num: int = 6, cell_width: int = 220,
                  cell_height: int = 200) -> Path:
    """A PNG grid: one row per panel (its title on the left), ``num`` evenly spaced frames per row
    (their times above), one camera for all; under it the whole timeline with the sampled times
    marked (dotted). Written atomically."""
    from PIL import Image, ImageDraw

    panels = list(panels)
    if not panels or not all(p.bodies for p in panels):
        raise ConvSynthError("nothing to render: every panel needs at least one body")
    n = min(b.num_frames for p in panels for b in p.bodies)
    frames = np.unique(np.linspace(0, n - 1, max(1, int(num))).round().astype(int))
    cw, ch = int(cell_width), int(cell_height)
    font, bold = _font(11), _font(12, bold=True)
    title_w = min(max(_text_width(p.title.replace("\n", "; "), bold) for p in panels) + 16, 180)
    top = 20
    width = title_w + len(frames) * (cw + 4)
    renderer = PanelRenderer([p.bodies for p in panels], cw, ch)
    strip = TimelineStrip(timelines, n / fps, width, None, markers=frames / fps) if timelines else None
    height = top + len(panels) * (ch + 4) + (strip.layout.height if strip else 0)
    im = Image.new("RGB", (width, height), PAGE_RGB)
    d = ImageDraw.Draw(im)
    for c, f in enumerate(frames):
        d.text((title_w + c * (cw + 4) + cw / 2, top / 2), f"{f / fps:.1f} s", font=font, fill=TEXT_RGB, anchor="mm")
    for i, p in enumerate(panels):
        y = top + i * (ch + 4)
        d.text((6, y + ch / 2), _fit(p.title.replace("\n", "; "), bold, title_w - 10), font=bold, fill=TEXT_RGB, anchor="lm")
        for c, f in enumerate(frames):
            im.paste(Image.fromarray(renderer.draw(p.bodies, int(f))), (title_w + c * (cw + 4), y))
    if strip is not None:
        im.paste(Image.fromarray(strip.view(0.0, cursor=False)), (0, top + len(panels) * (ch + 4)))
    path = Path(path)
    with atomic_path(path) as tmp:
        im.save(tmp, format="PNG")
    return path
