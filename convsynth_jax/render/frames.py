"""Frames: panels side by side under one camera, a header with titles and clock, the timeline below."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConvSynthError
from .raster import PanelRenderer
from .style import PAGE_RGB, TEXT_RGB
from .text import _fit, _font
from .timeline import TimelineStrip


@dataclass(frozen=True)
class Panel:
    """One view (e.g. "synthesized" or "ground truth") holding the bodies drawn together."""

    title: str
    bodies: tuple


class FrameRenderer:
    """Frames (H, W, 3) uint8 of ``panels`` side by side (one camera for all, fitted to every body),
    a header with the panels' titles and the clock, and the timeline underneath (see the module
    docstring). ``frame(f)``: the image at motion frame ``f``; ``layout``: where things lie."""

    HEADER = 22

    def __init__(self, panels, timelines, fps: float, panel_width: int = 480, panel_height: int = 360,
                 timeline_span_s: float | None = 15.0, yaw_deg: float = 35.0, pitch_deg: float = 12.0, clock: bool = True,
                 font_px: int = 11, markers=(), across=None):
        panels = list(panels)
        if not panels or not all(p.bodies for p in panels):
            raise ConvSynthError("nothing to render: every panel needs at least one body")
        self.panels, self.fps, self.clock = panels, float(fps), clock
        self.n = min(b.num_frames for p in panels for b in p.bodies)
        self.pw, self.ph = int(panel_width) + int(panel_width) % 2, int(panel_height) + int(panel_height) % 2
        self.renderer = PanelRenderer([p.bodies for p in panels], self.pw, self.ph, 1, yaw_deg, pitch_deg, across)
        self.width = len(panels) * self.pw + 2 * (len(panels) - 1)
        self.header = self.HEADER if (clock or any(p.title for p in panels)) else 0
        self.timeline = TimelineStrip(timelines, self.n / self.fps, self.width, timeline_span_s, font_px, markers) \
            if timelines else None
        self.height = self.header + self.ph + (self.timeline.layout.height if self.timeline else 0)
        self.height += self.height % 2
        self.font = _font(font_px + 1, bold=True)
        self.clock_font = _font(font_px)
        self._static = self._draw_static()

    def panel_box(self, i: int) -> tuple:
        """(col0, row0, col1, row1) of panel ``i`` in the frame."""
        x = i * (self.pw + 2)
        return x, self.header, x + self.pw, self.header + self.ph

    @property
    def timeline_top(self) -> int:
        return self.header + self.ph

    def _draw_static(self) -> np.ndarray:
        from PIL import Image, ImageDraw

        im = Image.new("RGB", (self.width, self.height), PAGE_RGB)
        d = ImageDraw.Draw(im)
        for i, p in enumerate(self.panels):
            x0, _, x1, _ = self.panel_box(i)
            if p.title:
                room = (x1 - x0) - (90 if (self.clock and i == len(self.panels) - 1) else 12)
                d.text((x0 + 6, self.header / 2), _fit(p.title.replace("\n", "; "), self.font, room), font=self.font,
                       fill=TEXT_RGB, anchor="lm")
            if i:
                d.rectangle([x0 - 2, self.header, x0 - 1, self.header + self.ph - 1], fill=(120, 120, 120))
        return np.asarray(im, np.uint8).copy()

    def _clock(self, img: np.ndarray, t: float) -> None:
        from PIL import Image, ImageDraw

        w, h = 84, self.header
        patch = Image.fromarray(img[:h, self.width - w:].copy())
        ImageDraw.Draw(patch).text((w - 6, h / 2), f"{t:6.1f} s", font=self.clock_font, fill=TEXT_RGB, anchor="rm")
        img[:h, self.width - w:] = np.asarray(patch)

    def frame(self, f: int) -> np.ndarray:
        f = int(min(max(f, 0), self.n - 1))
        img = self._static.copy()
        for i, p in enumerate(self.panels):
            x0, y0, x1, y1 = self.panel_box(i)
            img[y0:y1, x0:x1] = self.renderer.draw(p.bodies, f)
        t = f / self.fps
        if self.timeline is not None:
            tl = self.timeline.view(t)
            img[self.timeline_top:self.timeline_top + tl.shape[0]] = tl
        if self.clock and self.header:
            self._clock(img, t)
        return img

    def frames(self, step: int = 1):
        for f in range(0, self.n, max(1, int(step))):
            yield self.frame(f)
