"""Continuity at the joins of the sampler's windows (a sampling step, separate from the model)."""
from __future__ import annotations

import numpy as np


def window_starts(num_frames: int, window: int, prefix: int) -> list[int]:
    """First frames of the sampling windows of ``flow.model.sample_sequence`` over ``num_frames``."""
    hop = max(window - prefix, 1)
    return [0] + list(range(hop, max(num_frames - prefix, 1), hop)) if num_frames > window else [0]


def smooth_joins(x: np.ndarray, window: int, prefix: int, frames: int) -> np.ndarray:
    """``x`` (N, D) sampled in windows of ``window`` frames overlapping by ``prefix``, with each
    window's jump at its first generated frame (its departure from the linear continuation of the
    two frames before it) decayed linearly over ``frames`` frames (an inertialization of the join).
    A window's last ``prefix`` frames, the next window's prefix, are never changed when
    prefix + frames <= window - prefix, so this equals correcting each window as it is made."""
    x = np.array(x, np.float64, copy=True)
    if frames <= 0 or prefix < 2:
        return x
    for s in window_starts(len(x), window, prefix)[1:]:
        g = s + prefix                    # the first generated frame of this window
        if g >= len(x):
            break
        jump = x[g] - (2.0 * x[g - 1] - x[g - 2])
        k = min(int(frames), len(x) - g, window - prefix)
        x[g:g + k] -= jump[None, :] * (1.0 - np.arange(k) / float(frames))[:, None]
    return x
