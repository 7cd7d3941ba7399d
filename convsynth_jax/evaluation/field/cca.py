"""Canonical correlation analysis, fitted once on an evaluation set and applied to each window.

GENEA's script refits a CCA on every sequence, which lets each sequence pick its own projection (a
known pitfall: the score then rewards almost any motion). Here one CCA is fitted on all frames of a
system's windows pooled (:func:`fit_cca`): its first canonical correlation is the set's score, and
each window is scored by the correlation of its frames under that one pair of projections
(:func:`projected_correlation`). CCA_m compares synthesized with ground-truth motion, CCA_ms speech
with motion (Sadoughi and Busso, Sec. VIII-A; speech features: :func:`speech_cca_features`).
"""
from __future__ import annotations

import numpy as np

from ...stats.cca import (CCAFit, cca_from_covariances, correlation_from_moments, fit_cca,  # noqa: F401  (one home)
                         projected_correlation)


def speech_cca_features(audio, num_frames: int, fps: float, params) -> np.ndarray:
    """(num_frames, 4) speech features at the motion frame rate: F0 (Hz; unvoiced frames
    interpolated, 0 for a window without voice), log RMS energy (dB) and their first derivatives
    per second (the prosodic features of Sadoughi and Busso's CCA_ms). ``params``: :class:`CCAParams`."""
    from ...annotate.audio import f0_contour

    x = np.asarray(audio.samples, np.float64)
    x = x.mean(axis=1) if x.ndim > 1 else x
    sr = float(audio.sample_rate)
    t = np.arange(num_frames) / float(fps)
    try:
        ft, f0 = f0_contour(audio, time_step=1.0 / fps, floor=params.f0_floor, ceiling=params.f0_ceiling)
    except Exception:   # Praat refuses audio shorter than its analysis window
        ft, f0 = np.zeros(0), np.zeros(0)
    voiced = np.isfinite(f0)
    f = np.interp(t, ft[voiced], f0[voiced]) if voiced.sum() >= 2 else np.zeros(num_frames)
    n = max(2, int(round(params.energy_window * sr)))
    starts = np.clip(np.round(t * sr).astype(np.int64) - n // 2, 0, max(len(x) - n, 0))
    idx = np.clip(starts[:, None] + np.arange(n)[None, :], 0, max(len(x) - 1, 0))
    frames = x[idx] if len(x) else np.zeros((num_frames, n))
    e = 10.0 * np.log10(np.mean(frames ** 2, axis=1) + 1e-10)
    d = np.stack([f, e], axis=1)
    return np.concatenate([d, np.gradient(d, axis=0) * fps if num_frames > 1 else np.zeros_like(d)], axis=1)
