"""Leave-one-out test windows: slide a fixed window with a fixed hop over a held-out session."""
from __future__ import annotations

from dataclasses import dataclass

import pandas as pd


@dataclass(frozen=True)
class Window:
    index: int
    start: float  # seconds
    end: float    # seconds

    @property
    def duration(self) -> float:
        return self.end - self.start


def sliding_windows(duration: float, length: float = 15.0, hop: float = 14.0) -> list[Window]:
    """Windows [k*hop, k*hop + length) that fit entirely inside ``duration`` seconds."""
    if length <= 0 or hop <= 0:
        raise ValueError("window length and hop must be positive")
    out = []
    k = 0
    while k * hop + length <= duration + 1e-9:
        out.append(Window(k, k * hop, k * hop + length))
        k += 1
    return out


def window_segments(segments: pd.DataFrame, window: Window) -> pd.DataFrame:
    """Audio segments overlapping ``window``, with times relative to the window start.

    Segments that cross a window edge keep their true (unclipped) times, so their start may be
    negative or their end may exceed the window length: the search checks only what lies inside.
    """
    if segments is None or len(segments) == 0:
        return pd.DataFrame(columns=["kind", "start", "peak", "end", "text"])
    seg = segments[(segments["end"] > window.start) & (segments["start"] < window.end)].copy()
    for col in ("start", "peak", "end"):
        if col in seg:
            seg[col] = seg[col] - window.start
    return seg.reset_index(drop=True)
