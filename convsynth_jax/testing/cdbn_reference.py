"""Slow, obvious float64 NumPy references of the HMM kernels (plain loops, probabilities in log space
with scipy's logsumexp), used only by the tests. Tolerances of the comparisons live here too."""
from __future__ import annotations

import numpy as np
from scipy.special import logsumexp

# tolerances (the one place the CDBN tests take them from)
POSTERIOR_ATOL = 1e-5      # JAX smoother/filter (float64) vs reference
LOGLIK_RTOL = 1e-9         # JAX log-likelihood (float64) vs reference
MONOTONE_ATOL = 1e-9       # EM per-frame log-likelihood may not fall by more than this (float64)
XI_FLOAT32_RTOL = 1e-5     # float32 expected transition counts vs reference (relative ...
XI_FLOAT32_ATOL = 1e-5     # ... and absolute, per count)
POSTERIOR_FLOAT32_ATOL = 1e-5   # float32 smoother vs reference
LOGLIK_FLOAT32_RTOL = 1e-6      # float32 log-likelihood vs reference


def log_gauss(x, mean, cov):
    """log N(x; mean, cov) for x (T, d) by an explicit inverse and determinant."""
    d = len(mean)
    inv = np.linalg.inv(cov)
    _, logdet = np.linalg.slogdet(cov)
    out = np.empty(len(x))
    for t in range(len(x)):
        r = x[t] - mean
        out[t] = -0.5 * (r @ inv @ r + logdet + d * np.log(2 * np.pi))
    return out


def log_emissions(x, means, covs, dims):
    dims = list(dims)
    return np.stack([log_gauss(x[:, dims], means[k, dims], covs[k][np.ix_(dims, dims)])
                     for k in range(len(means))], axis=1)


def forward_backward(initial, transitions, loglik, constraints):
    """Log-space forward-backward with per-frame constraint c_t. Returns (loglik, filtered, smoothed,
    xi_sum (C, K, K))."""
    T, K = loglik.shape
    with np.errstate(divide="ignore"):
        la, lp = np.log(transitions), np.log(initial)
    alpha = np.zeros((T, K))
    alpha[0] = lp[constraints[0]] + loglik[0]
    for t in range(1, T):
        for j in range(K):
            alpha[t, j] = logsumexp(alpha[t - 1] + la[constraints[t]][:, j]) + loglik[t, j]
    beta = np.zeros((T, K))
    for t in range(T - 2, -1, -1):
        for i in range(K):
            beta[t, i] = logsumexp(la[constraints[t + 1]][i] + loglik[t + 1] + beta[t + 1])
    ll = logsumexp(alpha[-1])
    filt = np.exp(alpha - logsumexp(alpha, axis=1, keepdims=True))
    smooth = np.exp(alpha + beta - ll)
    xi = np.zeros((transitions.shape[0], K, K))
    for t in range(1, T):
        c = constraints[t]
        xi[c] += np.exp(alpha[t - 1][:, None] + la[c] + (loglik[t] + beta[t])[None, :] - ll)
    return ll, filt, smooth, xi


def viterbi(initial, transitions, loglik, constraints):
    T, K = loglik.shape
    with np.errstate(divide="ignore"):
        la, lp = np.log(transitions), np.log(initial)
    delta = lp[constraints[0]] + loglik[0]
    ptr = np.zeros((T, K), int)
    for t in range(1, T):
        new = np.empty(K)
        for j in range(K):
            s = delta + la[constraints[t]][:, j]
            ptr[t, j] = int(np.argmax(s))
            new[j] = s[ptr[t, j]] + loglik[t, j]
        delta = new
    path = np.zeros(T, int)
    path[-1] = int(np.argmax(delta))
    for t in range(T - 1, 0, -1):
        path[t - 1] = ptr[t, path[t]]
    return path, float(delta.max())
