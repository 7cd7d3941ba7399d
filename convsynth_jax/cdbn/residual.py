"""The spectral residual (ours, ``cdbn.synth.residual=spectral``): the motion the posterior-weighted
means leave out, put back with the recordings' spectrum.

The paper's output is an expected value (Eq. 4 / 6), smoothed by key points (15/s head, 12/s hands,
Sec. VI-B). An expected value given speech alone has a fraction of the recordings' variance, and 15
key points per second cannot carry anything above 7.5 Hz, where most of a head's jerk lies. Drawing
from each state's Gaussian per frame puts the variance back as white noise (several times the
recordings' jerk): the states' covariances describe the spread within a state, not its time course.

Here the time course is learnt from the training clips themselves: the residual r = recording -
(the system's own output on the clip's speech: means, then key points) is measured per feature as
a power spectrum (Welch, 128-frame segments, averaged over clips weighted by length), with its SD and
its correlation across features; the median over segments (Welch's median average), so that a
rare glitch or jump in a recording does not set the texture of every window. At synthesis, white
noise with that correlation is shaped per feature by the square root of that spectrum (one FFT over
the window, the variance set by the spectrum itself, so a window has the recordings' variance at
the frequencies it spans), and added to the smoothed output. The sum has (in expectation, where the means and the residual are
uncorrelated) the recordings' power spectrum, hence their variance and jerk. Stationary: the residual
does not depend on the state or the constraint (those move the means).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import CDBNError

SEGMENT = 128   # Welch segment, frames


@dataclass(frozen=True)
class ResidualSpectrum:
    """freqs (F,) Hz; psd (F, d) one-sided power spectral density per feature; sd (d,); chol (d, d) the
    Cholesky factor of the features' correlation; fps the frame rate it was measured at."""

    freqs: np.ndarray
    psd: np.ndarray
    sd: np.ndarray
    chol: np.ndarray
    fps: float


def fit_residual_spectrum(residuals: list, fps: float, segment: int = SEGMENT) -> ResidualSpectrum:
    """The spectrum of ``residuals`` (a list of (T_i, d) arrays, each demeaned on its own; clips shorter
    than 16 frames are left out)."""
    from scipy.signal import welch

    clips = [np.asarray(r, np.float64) for r in residuals if len(r) >= 16]
    if not clips:
        raise CDBNError("spectral residual: no training clip of at least 16 frames")
    d = clips[0].shape[1]
    if any(c.ndim != 2 or c.shape[1] != d or not np.all(np.isfinite(c)) for c in clips):
        raise CDBNError(f"spectral residual: residuals must be finite (T, {d}) arrays")
    freqs = np.fft.rfftfreq(segment, 1.0 / fps)
    acc, weight = np.zeros((len(freqs), d)), 0.0
    for c in clips:
        c = c - c.mean(0)
        f, p = welch(c, fs=fps, nperseg=min(segment, len(c)), axis=0, average="median")
        acc += len(c) * np.stack([np.interp(freqs, f, p[:, k]) for k in range(d)], axis=1)
        weight += len(c)
    x = np.concatenate([c - c.mean(0) for c in clips])
    sd = x.std(0)
    corr = np.corrcoef(x, rowvar=False) if d > 1 else np.ones((1, 1))
    corr = np.nan_to_num(np.atleast_2d(corr)) + 1e-9 * np.eye(d)
    for k in range(d):
        corr[k, k] = 1.0 + 1e-9
    return ResidualSpectrum(freqs, acc / weight, sd, np.linalg.cholesky(corr), float(fps))


def draw_residual(spec: ResidualSpectrum, num_frames: int, rng: np.random.Generator) -> np.ndarray:
    """(num_frames, d): zero-mean noise with ``spec``'s per-feature power spectrum (hence its variance
    above the window's lowest frequency) and correlation."""
    n = int(num_frames)
    d = len(spec.sd)
    if n <= 0:
        return np.zeros((0, d))
    w = rng.standard_normal((n, d)) @ spec.chol.T
    f = np.fft.rfftfreq(n, 1.0 / spec.fps)
    # one-sided density S: variance = integral of S over 0..fps/2; irfft(W g) of white W (unit variance)
    # has variance (g_0^2 + 2 sum_k g_k^2) / n, so g_k^2 = S(f_k) fps / 2 gives sum_k S(f_k) fps / n
    psd = np.stack([np.interp(f, spec.freqs, spec.psd[:, k]) for k in range(d)], axis=1)
    gain = np.sqrt(np.maximum(psd, 0.0) * spec.fps / 2.0)
    gain[0] = 0.0   # zero mean
    return np.fft.irfft(np.fft.rfft(w, axis=0) * gain, n=n, axis=0)
