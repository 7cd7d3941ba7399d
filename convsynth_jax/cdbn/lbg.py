"""State initialization (Sec. VI-C): Linde-Buzo-Gray vector quantization versus random initialization.

LBG [22]: start from the global centroid; split codewords c -> c(1 + eps), c(1 - eps) (perturbation
along each codeword's spread, ours: eps times the data SD, so a zero codeword splits too) and refine
with Lloyd iterations. With ``lbg_split='all'`` every codeword splits each round (the classic doubling) and a number of
states that is not a power of two is reached by splitting only the codewords with the largest
distortion in the last round; with ``'greedy'`` (our default) only the codeword with the largest
distortion splits each round, which avoids the classic local optimum where one round's split
divides a compact cluster while two others share a codeword (the paper does not say which).
*Random* initialization (our reading of [23]): every state starts at the global mean plus a small
random offset (0.1 SD) with the global covariance — the flat start whose states converge towards the
average pose (the paper's Fig. 6a).
"""
from __future__ import annotations

import numpy as np

from ..errors import CDBNError
from .em import floor_covariance
from .params import DBNModel, TrainParams


def _assign(x: np.ndarray, codebook: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    d = (x ** 2).sum(1)[:, None] - 2 * x @ codebook.T + (codebook ** 2).sum(1)[None, :]
    lab = np.argmin(d, axis=1)
    return lab, np.maximum(d[np.arange(len(x)), lab], 0.0)


def lloyd(x: np.ndarray, codebook: np.ndarray, iters: int) -> tuple[np.ndarray, np.ndarray]:
    """k-means refinement of ``codebook`` (K, D) on x (N, D); empty cells keep their codeword."""
    cb = codebook.copy()
    for _ in range(iters):
        lab, _ = _assign(x, cb)
        cnt = np.bincount(lab, minlength=len(cb))
        sums = np.zeros_like(cb)
        np.add.at(sums, lab, x)
        nz = cnt > 0
        new = cb.copy()
        new[nz] = sums[nz] / cnt[nz, None]
        if np.allclose(new, cb):
            cb = new
            break
        cb = new
    lab, _ = _assign(x, cb)
    return cb, lab


def lbg(x: np.ndarray, num_codewords: int, params: TrainParams | None = None,
        rng: np.random.Generator | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Codebook (K, D) and labels (N,) of x (N, D) by LBG splitting + Lloyd refinement."""
    params = params or TrainParams()
    x = np.asarray(x, np.float64)
    if len(x) < num_codewords:
        raise CDBNError(f"too few frames per state: {len(x)} frames for {num_codewords} states")
    rng = rng or np.random.default_rng(params.seed)
    sd = x.std(0) + 1e-9
    cb = x.mean(0, keepdims=True)
    lab = np.zeros(len(x), int)
    while len(cb) < num_codewords:
        _, dist = _assign(x, cb)
        distortion = np.bincount(lab, weights=dist, minlength=len(cb))
        m = min(len(cb), num_codewords - len(cb)) if params.lbg_split == "all" else 1
        split = np.argsort(-distortion)[:m]
        delta = params.lbg_epsilon * sd * (1.0 + 0.1 * rng.standard_normal((m, x.shape[1])))
        keep = np.delete(cb, split, axis=0)
        cb = np.concatenate([keep, cb[split] + delta, cb[split] - delta])
        cb, lab = lloyd(x, cb, params.lloyd_iter)
    return cb, lab


def random_init_means(x: np.ndarray, num_states: int, rng: np.random.Generator) -> np.ndarray:
    return x.mean(0) + 0.1 * x.std(0) * rng.standard_normal((num_states, x.shape[1]))


def gaussians_from_labels(x: np.ndarray, labels: np.ndarray, num_states: int, speech_dims, motion_dims,
                          floor: float) -> tuple[np.ndarray, np.ndarray]:
    """Means (K, D) and block-diagonal floored covariances (K, D, D) of each cluster (an empty or
    one-frame cluster gets the global covariance)."""
    D = x.shape[1]
    gcov = np.cov(x.T)
    means = np.zeros((num_states, D))
    covs = np.zeros((num_states, D, D))
    for k in range(num_states):
        xs = x[labels == k]
        means[k] = xs.mean(0) if len(xs) else x.mean(0)
        full = np.cov(xs.T) if len(xs) > 1 else gcov
        for dims in (speech_dims, motion_dims):
            ix = np.ix_(dims, dims)
            covs[k][ix] = floor_covariance(np.atleast_2d(full[ix]), floor)[0]
    return means, covs


def dense_chain(num_states: int, num_constraints: int, self_transition: float) -> tuple[np.ndarray, np.ndarray]:
    """Uniform initial (C, K) and ergodic transitions (C, K, K) with ``self_transition`` on the diagonal."""
    K = num_states
    off = (1.0 - self_transition) / max(K - 1, 1)
    A = np.full((K, K), off)
    np.fill_diagonal(A, self_transition if K > 1 else 1.0)
    return (np.full((num_constraints, K), 1.0 / K), np.broadcast_to(A, (num_constraints, K, K)).copy())


def init_dbn(x: np.ndarray, num_states: int, speech_dims: tuple, motion_dims: tuple, params: TrainParams,
             rng: np.random.Generator, constraint_names: tuple = ("all",), method: str | None = None,
             feature_layout: tuple = ()) -> DBNModel:
    """An ergodic DBN initialized from frames x (N, D) by LBG (``method='lbg'``) or randomly."""
    method = method or params.init
    x = np.asarray(x, np.float64)
    if method == "lbg":
        _, lab = lbg(x, num_states, params, rng)
        means, covs = gaussians_from_labels(x, lab, num_states, speech_dims, motion_dims, params.covariance_floor)
    elif method == "random":
        means = random_init_means(x, num_states, rng)
        gcov = np.cov(x.T)
        covs = np.zeros((num_states,) + gcov.shape)
        for dims in (speech_dims, motion_dims):
            ix = np.ix_(dims, dims)
            covs[:, ix[0], ix[1]] = floor_covariance(gcov[ix], params.covariance_floor)[0]
    else:
        raise CDBNError(f"unknown initialization {method!r}; expected 'lbg' or 'random'")
    init, trans = dense_chain(num_states, len(constraint_names), params.self_transition)
    return DBNModel(means, covs, init, trans, tuple(speech_dims), tuple(motion_dims), tuple(constraint_names),
                    tuple(feature_layout))
