"""Eye blinks (paper Section 7.3): at the first audio peak, at later peaks at least 1 s after the
last blink, and a random one whenever 5 s pass without a blink. Each blink lasts 0.17 s: 0.07 s
closing, 0.10 s opening."""
from __future__ import annotations

import numpy as np

CLOSE, OPEN = 0.07, 0.10


def blink_times(peaks, duration: float, rng: np.random.Generator, min_gap: float = 1.0, max_gap: float = 5.0):
    times = []
    for p in sorted(float(x) for x in peaks if 0 <= x < duration):
        if not times or p - times[-1] >= min_gap:
            times.append(p)
    out = []
    last = 0.0
    for t in times + [duration]:
        while t - last > max_gap:  # a random blink somewhere in the next 5 s window, at least min_gap apart
            cand = last + rng.uniform(min_gap, max_gap)
            if cand >= duration:
                break
            out.append(cand)
            last = cand
        if t < duration:
            out.append(t)
            last = t
    return np.array(sorted(out))


def blink_curve(times, num_frames: int, fps: float) -> np.ndarray:
    """(F,) eyelid closure in [0, 1]: linear close over 0.07 s, open over 0.10 s."""
    t = np.arange(num_frames) / fps
    curve = np.zeros(num_frames)
    for b in times:
        x = t - b
        c = np.where((x >= 0) & (x < CLOSE), x / CLOSE, 0.0)
        o = np.where((x >= CLOSE) & (x < CLOSE + OPEN), 1.0 - (x - CLOSE) / OPEN, 0.0)
        curve = np.maximum(curve, c + o)
    return curve
