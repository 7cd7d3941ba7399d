"""Key states (paper Section 6): frames where the audio status changes, plus keyframes sampled
adaptively by accumulated joint-position change (more where joints move, fewer at rest)."""
from __future__ import annotations

import numpy as np


def audio_change_states(db) -> np.ndarray:
    """(N,) bool: the own or partner label differs from the previous frame of the same clip; the
    first frame of every clip counts as a change."""
    n = db.num_frames
    change = np.zeros(n, bool)
    change[db.offsets[:-1]] = True
    for lab in (db.own.label, db.partner.label):
        d = np.zeros(n, bool)
        d[1:] = lab[1:] != lab[:-1]
        change |= d
    change[db.offsets[:-1]] = True
    return change


def pose_change(db) -> np.ndarray:
    """(N,) weighted joint-position change since the previous frame (0 at clip starts)."""
    d = np.linalg.norm(np.diff(db.positions, axis=0), axis=-1) @ db.weights
    out = np.concatenate([[0.0], d]).astype(np.float64)
    out[db.offsets[:-1]] = 0.0
    return out


def keyframes(db, step: float) -> np.ndarray:
    """(N,) bool: a keyframe each time the accumulated pose change in a clip crosses a multiple of step."""
    return _keyframes(pose_change(db), np.asarray(db.offsets), step)


def _keyframes(ch: np.ndarray, offsets: np.ndarray, step: float) -> np.ndarray:
    """Vectorized over clips: the accumulated change of frame t in its clip is the global running
    sum minus the sum before the clip's first frame (ch is 0 there)."""
    n = ch.size
    total = np.cumsum(ch)
    lengths = np.diff(offsets)
    start = np.repeat(offsets[:-1], lengths)
    acc = total - total[start]
    level = np.floor(acc / step)
    key = np.zeros(n, bool)
    key[1:] = level[1:] > level[:-1]
    key[offsets[:-1]] = False
    return key


def key_states(db, fraction: float = 0.2225, use_audio: bool = True, tol: float = 0.002):
    """(N,) bool key states and the keyframe step, chosen by bisection so that about ``fraction``
    of all frames are key states (audio-change states included). fraction >= 1: every frame."""
    n = db.num_frames
    if fraction >= 1.0:
        return np.ones(n, bool), 0.0
    base = audio_change_states(db) if use_audio else np.zeros(n, bool)
    base[db.offsets[:-1]] = True
    target = fraction * n
    if base.sum() >= target:
        return base, float("inf")
    ch = pose_change(db)
    offsets = np.asarray(db.offsets)
    total = ch.sum()
    lo, hi = total / n / 100.0, total + 1.0
    best = None
    for _ in range(60):
        mid = np.sqrt(lo * hi)
        k = base | _keyframes(ch, offsets, mid)
        cnt = k.sum()
        best = (k, mid)
        if abs(cnt - target) <= tol * n:
            break
        if cnt > target:
            lo = mid
        else:
            hi = mid
    return best
