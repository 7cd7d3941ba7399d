"""Canonical correlation analysis: the project's one definition (the field metrics' CCA_m / CCA_ms,
:mod:`convsynth_jax.evaluation.field.cca`; the constrained DBN's evaluation,
:func:`convsynth_jax.cdbn.evaluate.cca`).

The first canonical pair of two sets of variables: each covariance block whitened with a ridge of
``ridge`` times the block's mean variance (scale-free: the same correlation for data in cm or m),
then the top singular vectors of the whitened cross-covariance.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np


class CCAFit(NamedTuple):
    """x_mean (p,), y_mean (q,), x_weights (p,), y_weights (q,), rho: the first canonical correlation."""

    x_mean: np.ndarray
    y_mean: np.ndarray
    x_weights: np.ndarray
    y_weights: np.ndarray
    rho: float


def _inv_sqrt(c: np.ndarray, floor: float) -> np.ndarray:
    w, v = np.linalg.eigh(c)
    return (v / np.sqrt(np.maximum(w, floor))) @ v.T


def cca_from_covariances(cxx: np.ndarray, cyy: np.ndarray, cxy: np.ndarray, ridge: float = 1e-6):
    """(x_weights (p,), y_weights (q,), rho) of the first canonical pair of the covariance blocks:
    whiten each block, the top singular vectors of the whitened cross-covariance. ``ridge`` times
    the block's mean variance is added to its diagonal (and floors its eigenvalues)."""
    rx = ridge * max(float(np.trace(cxx)) / cxx.shape[0], 1e-300)
    ry = ridge * max(float(np.trace(cyy)) / cyy.shape[0], 1e-300)
    wx = _inv_sqrt(cxx + rx * np.eye(len(cxx)), rx)
    wy = _inv_sqrt(cyy + ry * np.eye(len(cyy)), ry)
    u, s, vt = np.linalg.svd(wx @ cxy @ wy)
    return wx @ u[:, 0], wy @ vt[0], float(np.clip(s[0], 0.0, 1.0))


def fit_cca(x: np.ndarray, y: np.ndarray, ridge: float = 1e-6) -> CCAFit:
    """First canonical pair of x (T, p) and y (T, q) (:func:`cca_from_covariances`)."""
    x = np.asarray(x, np.float64).reshape(len(x), -1)
    y = np.asarray(y, np.float64).reshape(len(y), -1)
    mx, my = x.mean(0), y.mean(0)
    xc, yc = x - mx, y - my
    n = max(len(x), 1)
    a, b, rho = cca_from_covariances(xc.T @ xc / n, yc.T @ yc / n, xc.T @ yc / n, ridge)
    return CCAFit(mx, my, a, b, rho)


def correlation_from_moments(n: float, s: np.ndarray, ss: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """Correlation of z[:p] @ a and z[p:] @ b (p = len(a)) from the moments of z = [x, y] over some
    frames: n frames, s = sum z, ss = sum z z^T. NaN for a constant projection."""
    if n < 2:
        return float("nan")
    mu = s / n
    c = ss / n - np.outer(mu, mu)
    p = len(a)
    va, vb, cab = a @ c[:p, :p] @ a, b @ c[p:, p:] @ b, a @ c[:p, p:] @ b
    return float(cab / np.sqrt(va * vb)) if va > 0 and vb > 0 else float("nan")


def projected_correlation(fit: CCAFit, x: np.ndarray, y: np.ndarray) -> float:
    """Pearson correlation of x @ x_weights and y @ y_weights over the frames of one window (NaN
    when either projection is constant)."""
    a = (np.asarray(x, np.float64).reshape(len(x), -1) - fit.x_mean) @ fit.x_weights
    b = (np.asarray(y, np.float64).reshape(len(y), -1) - fit.y_mean) @ fit.y_weights
    a, b = a - a.mean(), b - b.mean()
    den = np.sqrt((a @ a) * (b @ b))
    return float(a @ b / den) if den > 0 else float("nan")
