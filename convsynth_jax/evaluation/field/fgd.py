"""Fréchet gesture distance (Yoon et al. 2020; GENEA 2022): the Fréchet distance between Gaussians
fitted to two sets of feature vectors, in float64, with scipy's matrix square root and the usual
retry with ``eps`` on both diagonals when the square root is not finite (as the FID code does).
Features: raw windows of root-relative positions (:func:`raw_window_features`) or the latent
codes of our motion autoencoder (:mod:`.autoencoder`).
"""
from __future__ import annotations

import logging
import warnings

import numpy as np
import scipy.linalg

log = logging.getLogger(__name__)


def gaussian_stats(features: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(mean (d,), covariance (d, d)) of features (N, d), float64."""
    f = np.asarray(features, np.float64).reshape(len(features), -1)
    return f.mean(axis=0), np.atleast_2d(np.cov(f, rowvar=False))


def frechet_distance(mu1, sigma1, mu2, sigma2, eps: float = 1e-6) -> float:
    """|mu1 - mu2|^2 + tr(S1 + S2 - 2 (S1 S2)^(1/2))."""
    mu1, mu2 = np.asarray(mu1, np.float64), np.asarray(mu2, np.float64)
    s1, s2 = np.atleast_2d(np.asarray(sigma1, np.float64)), np.atleast_2d(np.asarray(sigma2, np.float64))
    diff = mu1 - mu2
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", scipy.linalg.LinAlgWarning)
        covmean = scipy.linalg.sqrtm(s1 @ s2)
    if not np.isfinite(covmean).all() or any(issubclass(w.category, scipy.linalg.LinAlgWarning) for w in caught):
        log.debug("Fréchet distance: singular product of covariances; adding %g to the diagonals", eps)
        off = np.eye(s1.shape[0]) * eps
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", scipy.linalg.LinAlgWarning)
            covmean = scipy.linalg.sqrtm((s1 + off) @ (s2 + off))
    if np.iscomplexobj(covmean):
        covmean = covmean.real
    return float(max(0.0, diff @ diff + np.trace(s1) + np.trace(s2) - 2.0 * np.trace(covmean)))


def fgd(features_a: np.ndarray, features_b: np.ndarray, eps: float = 1e-6) -> float:
    """Fréchet distance between the Gaussians of two feature sets (N, d) and (M, d)."""
    return frechet_distance(*gaussian_stats(features_a), *gaussian_stats(features_b), eps=eps)


def sqrt_psd(sigma: np.ndarray) -> np.ndarray:
    """Symmetric square root of a covariance (negative round-off eigenvalues clipped to 0)."""
    w, v = np.linalg.eigh(np.asarray(sigma, np.float64))
    return (v * np.sqrt(np.clip(w, 0.0, None))) @ v.T


def frechet_distance_eig(mu1, sigma1, mu2, sigma2, sqrt_sigma2: np.ndarray | None = None) -> float:
    """The same distance through symmetric eigenvalues, tr (S1 S2)^(1/2) = tr (R S1 R)^(1/2) with
    R = S2^(1/2) (``sqrt_sigma2``, computed when None), for the many resamples of the bootstrap
    intervals (symmetric eigendecompositions instead of a Schur square root; R is shared by every
    system compared with one reference)."""
    diff = np.asarray(mu1, np.float64) - np.asarray(mu2, np.float64)
    r = sqrt_psd(sigma2) if sqrt_sigma2 is None else sqrt_sigma2
    m = r @ np.asarray(sigma1, np.float64) @ r
    tr = float(np.sum(np.sqrt(np.clip(np.linalg.eigvalsh((m + m.T) / 2.0), 0.0, None))))
    return float(max(0.0, diff @ diff + np.trace(sigma1) + np.trace(sigma2) - 2.0 * tr))


def frame_windows(x: np.ndarray, length: int, stride: int | None = None) -> np.ndarray:
    """(N, length, ...) windows of x (F, ...) with ``stride`` (default half a window); none when
    F < length."""
    x = np.asarray(x)
    stride = stride or max(1, length // 2)
    starts = range(0, x.shape[0] - length + 1, stride)
    if x.shape[0] < length:
        return np.zeros((0, length) + x.shape[1:], x.dtype)
    return np.stack([x[s:s + length] for s in starts])


def raw_window_features(relative_positions: np.ndarray, length: int, step: int) -> np.ndarray:
    """(N, ceil(length / step) * J * 3) raw-window features: windows of ``length`` frames (stride
    half a window) of root-relative positions (F, J, 3), every ``step``-th frame, flattened."""
    w = frame_windows(np.asarray(relative_positions, np.float64), length)
    return w[:, ::step].reshape(len(w), -1)
