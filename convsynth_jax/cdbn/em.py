"""EM training of the (constrained) DBN (Sec. VI-C, VII-B): E-step = the JAX smoother of
:mod:`.hmm` over a padded batch of sequences; M-step in float64 NumPy: Gaussian means and full
covariances per stream (block-diagonal joint covariance: speech and motion independent given the
state) with an eigenvalue floor, per-constraint initial and transition probabilities. Exact zeros of
the transition and initial probabilities (the sparse structure of Sec. VII-B) receive zero expected
counts and therefore stay exactly zero.
"""
from __future__ import annotations

import logging
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

from ..errors import CDBNError
from .hmm import batch_statistics, pad_states
from .params import DBNModel, TrainParams

log = logging.getLogger(__name__)


class Batch(NamedTuple):
    """Padded sequences. x: (B, T, D) float32; constraints: (B, T) int32; lengths: (B,) int32 valid
    frames of each row (a prefix); resets: (B, T) bool, True at the first frame of every sequence
    (None: one sequence per row, starting at frame 0). T is rounded up to a power of two (at least
    ``bucket``) and B to a power of two (a multiple of 16 above 16) so that datasets of similar size
    share one compiled E-step; padding rows have length 0. A packed batch (``make_batch(pack=True)``)
    holds several sequences back to back in one row: the chain restarts from the initial distribution
    at each reset and no transition crosses it, so its statistics equal the unpacked batch's."""

    x: np.ndarray
    constraints: np.ndarray
    lengths: np.ndarray
    resets: np.ndarray | None = None

    def reset_mask(self) -> np.ndarray:
        """(B, T) bool: the first frame of every sequence."""
        if self.resets is not None:
            return self.resets
        r = np.zeros(self.constraints.shape, bool)
        r[:, 0] = True
        return r

    @property
    def num_frames(self) -> int:
        return int(self.lengths.sum())

    def valid(self) -> np.ndarray:
        """(B, T) bool mask of real frames."""
        return np.arange(self.x.shape[1])[None, :] < self.lengths[:, None]

    def frames(self) -> tuple[np.ndarray, np.ndarray]:
        """All valid frames (N, D) float64 and their constraints (N,)."""
        m = self.valid()
        return self.x[m].astype(np.float64), self.constraints[m]


def make_batch(sequences: Sequence[np.ndarray], constraints: Sequence[np.ndarray] | None = None,
               max_length: int | None = 2048, bucket: int = 64, dtype=np.float32, pack: bool = False,
               pack_length: int = 512) -> Batch:
    """Pad a list of (T_i, D) sequences (and (T_i,) constraint codes; zeros if None) into a Batch.
    Sequences longer than ``max_length`` are cut into consecutive chunks (the chain restarts from the
    initial distribution at each cut: a negligible approximation for long recordings that keeps the
    sequential scan short; None: never cut). ``pack``: put several sequences back to back in one row
    of the bucketed length (first-fit decreasing), so that the scans run over about the real number
    of frames instead of B x (a power of two above the longest); exact (see :class:`Batch`), for
    the E-step; rows then no longer correspond to sequences. Packed rows are at least ``pack_length``
    frames long, so that the datasets of one evaluation (all turns, each constraint's runs) share a
    few compiled shapes."""
    xs, cs = [], []
    for i, s in enumerate(sequences):
        s = np.asarray(s)
        c = np.zeros(len(s), np.int32) if constraints is None else np.asarray(constraints[i], np.int32)
        if len(c) != len(s):
            raise CDBNError(f"sequence {i}: {len(s)} frames but {len(c)} constraint codes")
        if len(s) == 0:
            continue
        step = len(s) if not max_length else max_length
        for a in range(0, len(s), step):
            xs.append(s[a:a + step])
            cs.append(c[a:a + step])
    if not xs:
        raise CDBNError("no frames to train on")
    T = max(len(s) for s in xs)
    T = max(bucket, int(2 ** np.ceil(np.log2(T))))           # bucketed shapes: few compilations
    if pack:
        T = max(T, int(pack_length))
        rows, used = [], []              # first-fit decreasing: lists of sequence indices per row
        for i in sorted(range(len(xs)), key=lambda i: -len(xs[i])):
            r = next((j for j, u in enumerate(used) if u + len(xs[i]) <= T), None)
            if r is None:
                rows.append([i])
                used.append(len(xs[i]))
            else:
                rows[r].append(i)
                used[r] += len(xs[i])
    else:
        rows = [[i] for i in range(len(xs))]
    B = len(rows)
    B = int(2 ** np.ceil(np.log2(B))) if B <= 16 else int(np.ceil(B / 16) * 16)
    D = xs[0].shape[1]
    x = np.zeros((B, T, D), dtype)
    cc = np.zeros((B, T), np.int32)
    lengths = np.zeros(B, np.int32)      # padding rows have length 0
    resets = np.zeros((B, T), bool)
    resets[:, 0] = True
    for r, members in enumerate(rows):
        a = 0
        for i in members:
            s, c = xs[i], cs[i]
            x[r, a:a + len(s)] = s
            cc[r, a:a + len(s)] = c
            resets[r, a] = True
            a += len(s)
        cc[r, a:] = cc[r, a - 1]
        lengths[r] = a
    return Batch(x, cc, lengths, resets if pack else None)


class Stats(NamedTuple):
    """Expected sufficient statistics of one E-step (float64). log_likelihood: total over sequences;
    counts: (K,); first: (K, D) sum gamma x; second: (K, D, D) sum gamma x x^T;
    initial: (C, K) expected first states per first constraint; transitions: (C, K, K)."""

    log_likelihood: float
    counts: np.ndarray
    first: np.ndarray
    second: np.ndarray
    initial: np.ndarray
    transitions: np.ndarray


def e_step(model: DBNModel, batch: Batch, dims: tuple | None = None) -> Stats:
    """Smoother over the batch and the expected sufficient statistics (reduced on the device, about
    the batch mean, converted to float64 raw moments here)."""
    D = batch.x.shape[-1]
    dims = tuple(range(D)) if dims is None else tuple(dims)
    dt = batch.x.dtype
    shift = batch.x[batch.valid()].mean(0) if batch.num_frames else np.zeros(D, dt)
    K = model.num_states
    means, covs, initial, trans = pad_states(model.means, model.covariances, model.initial, model.transitions)
    out = batch_statistics(jnp.asarray(batch.x), jnp.asarray(batch.constraints), jnp.asarray(batch.lengths),
                           jnp.asarray(batch.reset_mask()), jnp.asarray(shift, dt), jnp.asarray(means, dt),
                           jnp.asarray(covs, dt), jnp.asarray(initial, dt), jnp.asarray(trans, dt), dims)
    ll, counts, first, second, init, xi = (np.asarray(o, np.float64) for o in out)
    counts, first, second, init, xi = counts[:K], first[:K], second[:K], init[:, :K], xi[:, :K, :K]
    shift = shift.astype(np.float64)
    # raw moments: sum g x = first + n shift; sum g x x^T = second + first shift^T + shift first^T + n shift shift^T
    raw1 = first + counts[:, None] * shift
    raw2 = (second + first[:, :, None] * shift[None, None, :] + shift[None, :, None] * first[:, None, :]
            + counts[:, None, None] * np.outer(shift, shift)[None])
    return Stats(float(ll), counts, raw1, raw2, init, xi)


def floor_covariance(cov: np.ndarray, floor: float, where: str = "") -> tuple[np.ndarray, bool]:
    """Clip the eigenvalues of a symmetric matrix at ``floor`` (the constrained ML covariance);
    returns (matrix, whether anything was clipped)."""
    cov = 0.5 * (cov + cov.T)
    w, v = np.linalg.eigh(cov)
    if w.min() >= floor:
        return cov, False
    w = np.maximum(w, floor)
    return (v * w) @ v.T, True


def m_step(model: DBNModel, st: Stats, params: TrainParams, warn: bool = True, floored_out: list | None = None) -> DBNModel:
    """Maximization (float64). States without responsibility keep their Gaussians; transition rows
    and initial vectors without counts keep their previous values; zeros stay zeros."""
    K, D = model.means.shape
    means = model.means.astype(np.float64).copy()
    covs = model.covariances.astype(np.float64).copy()
    floored = []
    for k in range(K):
        n = st.counts[k]
        if n < 1e-8:
            continue
        mu = st.first[k] / n
        full = st.second[k] / n - np.outer(mu, mu)
        means[k] = mu
        new = np.zeros((D, D))
        for name, dims in (("speech", model.speech_dims), ("motion", model.motion_dims)):
            ix = np.ix_(dims, dims)
            block, clipped = floor_covariance(full[ix], params.covariance_floor)
            new[ix] = block
            if clipped:
                floored.append(f"state {k} {name}")
        covs[k] = new
    if floored_out is not None:
        floored_out.extend(floored)
    if floored and warn:
        warnings.warn(f"singular or near-singular covariances floored at eigenvalue {params.covariance_floor}: "
                      f"{', '.join(floored[:8])}{' ...' if len(floored) > 8 else ''}", RuntimeWarning, stacklevel=2)
    trans = model.transitions.astype(np.float64).copy()
    tmask = model.transitions > 0
    rows = (st.transitions * tmask).sum(-1, keepdims=True)
    upd = np.where(tmask, st.transitions, 0.0) / np.where(rows > 0, rows, 1.0)
    trans = np.where(rows > 1e-10, upd, trans)
    init = model.initial.astype(np.float64).copy()
    imask = model.initial > 0
    tot = (st.initial * imask).sum(-1, keepdims=True)
    init = np.where(tot > 1e-10, np.where(imask, st.initial, 0.0) / np.where(tot > 0, tot, 1.0), init)
    return model._replace(means=means, covariances=covs, initial=init, transitions=trans)


@dataclass
class EMFit:
    model: DBNModel
    log_likelihoods: list          # per-frame log-likelihood after each E-step (non-decreasing)
    converged: bool
    iterations: int


def fit_em(model: DBNModel, batch: Batch, params: TrainParams, max_iter: int | None = None,
           progress: bool = False) -> EMFit:
    """EM from ``model`` until the per-frame log-likelihood gains less than ``params.tol``."""
    n = batch.num_frames
    K = model.num_states
    if n < params.min_frames_per_state * K:
        raise CDBNError(f"too few frames per state: {n} training frames for {K} states "
                        f"(need at least {params.min_frames_per_state} per state, "
                        f"i.e. {params.min_frames_per_state * K}); use fewer states or more data")
    iters = params.max_iter if max_iter is None else max_iter
    lls, converged, floored = [], False, []
    for it in range(iters):
        st = e_step(model, batch)
        lls.append(st.log_likelihood / n)
        if not np.isfinite(lls[-1]):
            raise CDBNError(f"log-likelihood became {lls[-1]} at EM iteration {it}")
        if len(lls) > 1 and lls[-1] - lls[-2] < params.tol:
            converged = True
            break
        model = m_step(model, st, params, warn=False, floored_out=floored)
        if progress:
            log.info("EM iteration %d: log-likelihood per frame %.5f", it, lls[-1])
    if floored:
        uniq = sorted(set(floored))
        warnings.warn(f"singular or near-singular covariances floored at eigenvalue {params.covariance_floor} "
                      f"during EM: {', '.join(uniq[:6])}{' ...' if len(uniq) > 6 else ''}", RuntimeWarning, stacklevel=2)
    return EMFit(model, lls, converged, len(lls))
