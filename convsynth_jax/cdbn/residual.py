"""The spectral residual (ours, ``cdbn.synth.residual=spectral``): the motion the posterior-weighted
means leave out, put back with the recordings' spectrum.

The paper's output is an expected value (Eq. 4 / 6), smoothed by key points (15/s head, 12/s hands,
Sec. VI-B). An expected value given speech alone has a fraction of the recordings' variance, and 15
key points per second cannot carry anything above 7.5 Hz, where most of a head's jerk lies. Drawing
from each state's Gaussian per frame puts the variance back as white noise (several times the
recordings' jerk): the states' covariances describe the spread within a state, not its time course.

Here the time course is learnt from the training clips themselves: per feature and frequency, the
power the system's own output on the clips' speech (means, then key points) lacks against the
recordings (Welch, 128-frame segments, averaged over clips weighted by length; the recordings'
density minus the output's, clipped at zero: where the output has more, e.g. jumps between states,
nothing is added), with the correlation of recording - output across features; the median over
segments (Welch's median average), so that a rare glitch or jump in a recording does not set the
texture of every window. At synthesis, white
noise with that correlation is shaped per feature by the square root of that spectrum (one FFT over
the window, the variance set by the spectrum itself, so a window has the recordings' variance at
the frequencies it spans), and added to the smoothed output. The sum has (in expectation, where the means and the residual are
uncorrelated) the recordings' power spectrum wherever the output had less, hence their variance
and jerk where those were missing. Stationary: the residual
does not depend on the state or the constraint (those move the means).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import CDBNError

SEGMENT = 128   # Welch segment, frames


@dataclass(frozen=True)
class ResidualSpectrum:
    """freqs (F,) Hz; psd (F, d) one-sided power spectral density to add per feature; sd (d,) of
    recording - output (for reference); chol (d, d) the Cholesky factor of its correlation across
    features; fps the frame rate it was measured at."""

    freqs: np.ndarray
    psd: np.ndarray
    sd: np.ndarray
    chol: np.ndarray
    fps: float


def _welch_median(clips: list, freqs: np.ndarray, fps: float, segment: int) -> np.ndarray:
    """(F, d) length-weighted mean over clips of each clip's median-averaged Welch density."""
    from scipy.signal import welch

    d = clips[0].shape[1]
    acc, weight = np.zeros((len(freqs), d)), 0.0
    for c in clips:
        f, p = welch(c - c.mean(0), fs=fps, nperseg=min(segment, len(c)), axis=0, average="median")
        acc += len(c) * np.stack([np.interp(freqs, f, p[:, k]) for k in range(d)], axis=1)
        weight += len(c)
    return acc / weight


def fit_residual_spectrum(recordings: list, outputs: list, fps: float, segment: int = SEGMENT) -> ResidualSpectrum:
    """The power the system's ``outputs`` lack against the ``recordings`` (two lists of (T_i, d)
    arrays, the system's output on each recording's speech), per feature and frequency: the
    recordings' density minus the outputs', clipped at zero (where the output already has more power,
    e.g. the jumps between states, nothing is added). Clips shorter than 16 frames are left out; the
    correlation is that of recording - output."""
    if len(recordings) != len(outputs):
        raise CDBNError(f"spectral residual: {len(recordings)} recordings but {len(outputs)} outputs")
    pairs = [(np.asarray(r, np.float64), np.asarray(o, np.float64)) for r, o in zip(recordings, outputs) if len(r) >= 16]
    if not pairs:
        raise CDBNError("spectral residual: no training clip of at least 16 frames")
    d = pairs[0][0].shape[1]
    for i, (r, o) in enumerate(pairs):
        if r.ndim != 2 or r.shape[1] != d or r.shape != o.shape or not (np.all(np.isfinite(r)) and np.all(np.isfinite(o))):
            raise CDBNError(f"spectral residual: clip {i}: recording {r.shape} and output {o.shape} must be finite (T, {d}) arrays")
    freqs = np.fft.rfftfreq(segment, 1.0 / fps)
    psd = np.maximum(_welch_median([r for r, _ in pairs], freqs, fps, segment)
                     - _welch_median([o for _, o in pairs], freqs, fps, segment), 0.0)
    x = np.concatenate([(r - o) - (r - o).mean(0) for r, o in pairs])
    sd = x.std(0)
    corr = np.atleast_2d(np.nan_to_num(np.corrcoef(x, rowvar=False))) if d > 1 else np.ones((1, 1))
    corr = corr + 1e-9 * np.eye(d)
    for k in range(d):
        corr[k, k] = 1.0 + 1e-9
    return ResidualSpectrum(freqs, psd, sd, np.linalg.cholesky(corr), float(fps))


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
