"""The timeline under the panels: one row per speaker's audio labels, synthetic transitions as ticks,
a time axis and a legend; a long one scrolls around the cursor."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .style import BODY_RGB, CURSOR_RGB, LABEL_NAMES, LABEL_RGB, MUTED_RGB, OTHER_LABEL_RGB, PAGE_RGB, ROW_RGB, TEXT_RGB, TICK_RGB
from .text import _fit, _font, _text_width


@dataclass(frozen=True)
class Timeline:
    """One row of the timeline: ``segments`` (columns kind, start, end; seconds from the first frame)
    drawn as coloured bars (the kind written inside where it fits); ``ticks``: times (seconds) of
    synthetic transitions, drawn as ticks under the bars; ``color``: the index of the body whose
    colour the row's name is marked with (None: unmarked)."""

    name: str
    segments: pd.DataFrame = field(default_factory=lambda: pd.DataFrame(columns=["kind", "start", "end"]))
    ticks: tuple = ()
    color: int | None = None


def _label_rgb(kind: str):
    return LABEL_RGB.get(kind, OTHER_LABEL_RGB)


@dataclass(frozen=True)
class StripLayout:
    """Where the timeline's parts lie in its image (pixels; rows from its top): the gutter of names
    ``[0, gutter)``, the drawn time axis ``[x0, x0 + area)`` at ``pps`` pixels per second (scrolled
    by ``offset(t)``), per row the bar ``(top, bottom)`` and tick band ``(top, bottom)``, the legend's
    rows, and each name's box (x0, y0, x1, y1)."""

    width: int
    height: int
    gutter: int
    x0: int
    area: int
    pps: float
    axis: tuple
    bars: tuple
    ticks: tuple
    legend: tuple
    names: tuple


class TimelineStrip:
    """The timeline under the panels (see the module docstring). ``view(t)``: the (height, width, 3)
    uint8 image at time ``t`` with its cursor; ``x_of(t, at)``: the column of time ``t`` in the image
    shown at time ``at``. Duration: seconds of motion shown; ``span_s``: the most seconds shown at
    once (None: all)."""

    ROW_BAR, ROW_TICK, ROW_GAP, AXIS_H, LEGEND_H, PAD = 16, 7, 5, 15, 16, 6

    def __init__(self, timelines, duration: float, width: int, span_s: float | None = 15.0, font_px: int = 11,
                 markers=()):
        self.timelines = [t for t in timelines if t is not None]
        self.duration = max(float(duration), 1e-6)
        self.font, self.small = _font(font_px), _font(max(font_px - 1, 6))
        width = int(width)
        names = [t.name for t in self.timelines]
        swatch = 12
        want = max([_text_width(n, self.font) for n in names] or [0]) + swatch + 2 * self.PAD
        gutter = int(min(want, 0.35 * width)) if names else self.PAD
        x0 = gutter + self.PAD
        area = max(width - x0 - self.PAD, 10)
        shown = self.duration if span_s is None else min(self.duration, float(span_s))
        pps = area / shown
        y = self.PAD
        axis = (y, y + self.AXIS_H)
        y = axis[1] + 2
        bars, ticks, boxes = [], [], []
        for t in self.timelines:
            bars.append((y, y + self.ROW_BAR))
            y += self.ROW_BAR
            ticks.append((y + 1, y + self.ROW_TICK))
            y += self.ROW_TICK + self.ROW_GAP
        present = {str(k) for t in self.timelines if len(t.segments) for k in t.segments["kind"].astype(str)}
        # the known labels in their order, then any other label drawn (e.g. a registered kind's, in grey)
        self.kinds = [k for k in LABEL_RGB if k in present] + sorted(present - set(LABEL_RGB))
        self.has_ticks = any(len(t.ticks) for t in self.timelines)
        legend_rows = self._legend_rows(width)
        legend = (y, y + self.LEGEND_H * len(legend_rows))
        height = legend[1] + self.PAD
        height += height % 2
        for t, (b0, _), (_, k1) in zip(self.timelines, bars, ticks):
            boxes.append((self.PAD, b0, gutter, k1))
        self.layout = StripLayout(width, height, gutter, x0, area, pps, axis, tuple(bars), tuple(ticks), legend,
                                  tuple(boxes))
        self._legend = legend_rows
        self.markers = tuple(float(m) for m in markers)
        self._static, self._strip = self._draw_static(), self._draw_strip()

    # -- layout helpers
    def _legend_rows(self, width: int) -> list:
        items = [(k, f"{k} {LABEL_NAMES.get(k, k)}") for k in self.kinds]
        if self.has_ticks:
            items.append(("tick", "synthetic transition"))
        rows, cur, x = [], [], self.PAD
        for it in items:
            w = 14 + _text_width(it[1], self.small) + 12
            if cur and x + w > width - self.PAD:
                rows.append(cur)
                cur, x = [], self.PAD
            cur.append(it)
            x += w
        if cur:
            rows.append(cur)
        return rows

    def offset(self, t: float) -> float:
        """Pixels of the strip scrolled out to the left at time ``t`` (0 while it all fits)."""
        L = self.layout
        total = self.duration * L.pps
        return float(np.clip(t * L.pps - 0.5 * L.area, 0.0, max(0.0, total - L.area)))

    def x_of(self, t: float, at: float | None = None) -> float:
        """The image column of time ``t`` when the strip shows time ``at`` (default: ``t``)."""
        L = self.layout
        return L.x0 + t * L.pps - self.offset(t if at is None else at)

    # -- drawing
    def _draw_static(self) -> np.ndarray:
        """The parts that never move: page, gutter with names and colour swatches, legend."""
        from PIL import Image, ImageDraw

        L = self.layout
        im = Image.new("RGB", (L.width, L.height), PAGE_RGB)
        d = ImageDraw.Draw(im)
        for t, (x0, y0, x1, _), (b0, b1) in zip(self.timelines, L.names, L.bars):
            tx = x0
            if t.color is not None:
                d.rectangle([x0, b0 + 3, x0 + 8, b1 - 4], fill=BODY_RGB[t.color % len(BODY_RGB)])
                tx = x0 + 12
            d.text((tx, (b0 + b1) / 2), _fit(t.name, self.font, x1 - tx), font=self.font, fill=TEXT_RGB, anchor="lm")
        y = L.legend[0]
        for row in self._legend:
            x = self.PAD
            for key, text in row:
                cy = y + self.LEGEND_H // 2
                if key == "tick":
                    d.rectangle([x + 4, cy - 5, x + 5, cy + 5], fill=TICK_RGB)
                else:
                    d.rectangle([x, cy - 4, x + 9, cy + 4], fill=_label_rgb(key))
                d.text((x + 14, cy), text, font=self.small, fill=MUTED_RGB, anchor="lm")
                x += 14 + _text_width(text, self.small) + 12
            y += self.LEGEND_H
        return np.asarray(im, np.uint8).copy()

    def _draw_strip(self) -> np.ndarray:
        """The whole duration at ``pps``: axis, bars, kind names, ticks (rows of the image, columns
        from time 0)."""
        from PIL import Image, ImageDraw

        L = self.layout
        w = int(np.ceil(self.duration * L.pps)) + 2
        im = Image.new("RGB", (w, L.height), PAGE_RGB)
        d = ImageDraw.Draw(im)
        for (b0, b1), (k0, k1), t in zip(L.bars, L.ticks, self.timelines):
            d.rectangle([0, b0, w - 1, b1 - 1], fill=ROW_RGB)
            for r in t.segments.itertuples(index=False):
                s, e = max(float(r.start), 0.0), min(float(r.end), self.duration)
                if e <= s:
                    continue
                xs, xe = s * L.pps, e * L.pps
                d.rectangle([int(round(xs)), b0, max(int(round(xe)) - 1, int(round(xs))), b1 - 1], fill=_label_rgb(str(r.kind)))
                label = str(r.kind)
                if _text_width(label, self.small) + 4 <= xe - xs:
                    d.text(((xs + xe) / 2, (b0 + b1) / 2), label, font=self.small, fill=(255, 255, 255), anchor="mm")
            for tick in t.ticks:
                if 0.0 <= tick <= self.duration:
                    x = int(round(float(tick) * L.pps))
                    d.rectangle([x, k0, x + 1, k1 - 1], fill=TICK_RGB)
        step = next((s for s in (0.5, 1, 2, 5, 10, 15, 30, 60, 120, 300, 600, 1800) if s * L.pps >= 48), 3600)
        a0, a1 = L.axis
        for k in range(int(self.duration / step) + 1):
            t = k * step
            x = int(round(t * L.pps))
            d.line([x, a1 - 4, x, a1 - 1], fill=MUTED_RGB)
            label = f"{t:g} s"
            tw = _text_width(label, self.small)
            d.text((min(max(x, tw / 2), w - tw / 2 - 1), a0 + 5), label, font=self.small, fill=MUTED_RGB, anchor="mm")
        for m in self.markers:
            x = int(round(m * L.pps))
            for yy in range(L.bars[0][0] if L.bars else a1, (L.ticks[-1][1] if L.ticks else a1), 3):
                d.point([(x, yy)], fill=(90, 90, 90))
        return np.asarray(im, np.uint8).copy()

    def view(self, t: float, cursor: bool = True) -> np.ndarray:
        """The timeline image at time ``t``: static parts, the strip's window, the cursor."""
        L = self.layout
        img = self._static.copy()
        off = int(round(self.offset(t)))
        part = self._strip[:L.legend[0], off:off + L.area]
        img[:L.legend[0], L.x0:L.x0 + part.shape[1]] = part
        if cursor and self.timelines:
            x = int(round(self.x_of(t)))
            if L.x0 <= x < L.x0 + L.area:
                img[L.axis[0]:L.ticks[-1][1], max(x - 1, 0):x + 1] = CURSOR_RGB
        return img
