"""What a synthesized window plays of its source recordings, from its per-frame provenance (the
source clip and frame of each output frame): how spread its visits are and which frames a blend
covers."""
from __future__ import annotations

import numpy as np


def source_visits(clips, frames, fps: float, source_still, source_speed) -> dict:
    """Per window: entropy (bits) of the (clip, source second) cells its frames come from, share of its
    most used clip, source seconds played again by a later excerpt (``revisited_seconds``), share of
    frames whose source frame is still (``source_still``, (T,) bool) and the mean of ``source_speed``
    ((T,), each frame's source speed over the recordings' mean)."""
    cells = np.array([f"{c}:{int(f // fps)}" for c, f in zip(clips, frames)])
    _, counts = np.unique(cells, return_counts=True)
    p = counts / counts.sum()
    _, per_clip = np.unique(np.asarray(clips), return_counts=True)
    frames = np.asarray(frames)
    cuts = np.flatnonzero((np.diff(frames) != 1) | (np.asarray(clips[1:]) != np.asarray(clips[:-1]))) + 1
    seen, revisits = set(), 0
    for seg in np.split(np.arange(len(frames)), cuts):
        secs = {(clips[seg[0]], int(frames[i] // fps)) for i in seg}
        revisits += len(secs & seen)
        seen |= secs
    return {"entropy_bits": float(-(p * np.log2(p)).sum()), "source_still_share": float(np.mean(source_still)),
            "top_clip_share": float(per_clip.max() / len(clips)), "revisited_seconds": revisits,
            "source_speed_ratio": float(np.mean(source_speed))}


def blend_mask(n: int, synthetic_at, blend_frames: int) -> np.ndarray:
    """(n,) bool: output frames within ``blend_frames`` after a synthetic transition."""
    m = np.zeros(n, bool)
    for t in synthetic_at:
        m[int(t):int(t) + blend_frames] = True
    return m
