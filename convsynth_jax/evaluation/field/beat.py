"""Beat consistency (BC), the definition of EMAGE (Liu et al. 2024) after BEAT (Liu et al. 2022).

Motion beats: for each upper-body joint, its speed divided by its mean speed over the window; the
frames where that ratio is a strict local minimum over ``order`` frames on each side and exceeds
``threshold`` (a pause in a moving joint, not stillness). Audio beats: librosa's onset times. Each
motion beat scores exp(-d^2 / (2 sigma^2)) for the distance d to its nearest audio beat; a joint's
score is the mean over its beats, the window's the mean over joints with beats. Both streams are
timed on the window's own clock (frame f at f / fps, from a central difference, so no half-frame
shift between them; EMAGE's script offsets one stream, which we do not copy), and beats within
``trim`` s of either end are left out of both.
"""
from __future__ import annotations

import numpy as np
from scipy.signal import argrelextrema

from .params import BeatParams


def joint_speed(positions: np.ndarray, fps: float) -> np.ndarray:
    """(F, J) speed of every joint at every frame (central differences, one-sided at the ends)."""
    p = np.asarray(positions, np.float64)
    if len(p) < 2:
        return np.zeros(p.shape[:2])
    return np.linalg.norm(np.gradient(p, axis=0), axis=-1) * fps


def motion_beats(positions: np.ndarray, fps: float, params: BeatParams) -> list[np.ndarray]:
    """Per joint of ``positions`` (F, J, 3): the times (s) of its motion beats."""
    speed = joint_speed(positions, fps)
    out = []
    for j in range(speed.shape[1]):
        v = speed[:, j]
        mean = v.mean() if v.size else 0.0
        if mean <= 0:
            out.append(np.zeros(0))
            continue
        r = v / mean
        idx = argrelextrema(r, np.less, order=params.order)[0]
        out.append(idx[r[idx] > params.threshold] / float(fps))
    return out


def audio_beats(audio, params: BeatParams) -> np.ndarray:
    """Onset times (s) of one window's audio by librosa's onset detector."""
    import librosa

    x = np.asarray(audio.samples, np.float32)
    x = x.mean(axis=1) if x.ndim > 1 else x
    if len(x) < params.hop_length * 4:
        return np.zeros(0)
    return np.asarray(librosa.onset.onset_detect(y=x, sr=int(audio.sample_rate), hop_length=params.hop_length,
                                                 units="time"), np.float64)


def beat_consistency(motion_beat_times: list[np.ndarray], audio_beat_times: np.ndarray, duration: float,
                     params: BeatParams) -> float:
    """BC of one window from its beats (see the module docstring); NaN when no audio beat or no
    motion beat lies inside the trimmed window."""
    lo, hi = params.trim, duration - params.trim
    a = np.asarray(audio_beat_times, np.float64)
    a = np.sort(a[(a >= lo) & (a <= hi)])
    if a.size == 0:
        return float("nan")
    scores = []
    for m in motion_beat_times:
        m = np.asarray(m, np.float64)
        m = m[(m >= lo) & (m <= hi)]
        if m.size == 0:
            continue
        k = np.clip(np.searchsorted(a, m), 1, max(a.size - 1, 1))
        d = np.minimum(np.abs(m - a[k - 1]), np.abs(m - a[np.minimum(k, a.size - 1)]))
        scores.append(float(np.mean(np.exp(-d ** 2 / (2.0 * params.sigma ** 2)))))
    return float(np.mean(scores)) if scores else float("nan")
