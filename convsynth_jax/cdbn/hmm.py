"""HMM inference for the (constrained) DBN in JAX: forward filter, backward pass, smoother, expected
transition counts and Viterbi, each a ``lax.scan`` over a named ``_step`` (dynamax style).

The constraint sequence c_t selects the transition matrix at every frame (Eq. 5:
a^k_ij = P(q_t = j | q_{t-1} = i, C_t = k)) and the initial distribution at the first frame.
Everything runs in log space (log-sum-exp over the previous state at every frame): structural zeros
of the transition matrices are -inf and stay exact, and no frame underflows even when the emissions
of every reachable state are thousands of nats below an unreachable one (a scaled float32
recursion, tried first, failed exactly there on concatenated held-out turns). The forward message is
renormalized per frame (the normalizers sum to the log-likelihood); the backward message is shifted
per frame (it is defined up to a per-frame factor); expected transitions are normalized per frame.

Primitives work on one sequence of ``T`` frames of which the first ``length`` are valid (the rest
is padding, so that batches of sequences share one compiled shape); batch them with ``jax.vmap``.
"""
from __future__ import annotations

from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax


class Posterior(NamedTuple):
    """log_likelihood: () log p(x_{1:length} | c, model); filtered / smoothed: (T, K) (padding rows
    are copies of the last valid one / undefined); xi_sum: (C, K, K) expected transition counts per
    constraint, sum_t P(q_{t-1}=i, q_t=j | x) over frames t with c_t = k."""

    log_likelihood: jnp.ndarray
    filtered: jnp.ndarray
    smoothed: jnp.ndarray
    xi_sum: jnp.ndarray


def gaussian_log_density(x, means, covariances):
    """log N(x_t; mu_k, Sigma_k). x: (T, d); means: (K, d); covariances: (K, d, d) -> (T, K).

    The Mahalanobis terms as one matrix product over frames: (x - mu)^T P (x - mu) with P = Sigma^-1
    expands into the products x_i x_j (T, d*d) against P (K, d*d), minus 2 x^T P mu, plus mu^T P mu,
    so no (K, T, d) array is formed (that array's memory traffic was most of the E-step on the CPU).
    Everything is centred first on the mean of the state means, which keeps the expansion's terms
    near the size of the result (checked against the float64 reference, also in float32)."""
    d = x.shape[-1]
    K = means.shape[0]
    centre = jnp.mean(means, axis=0)
    xc = x - centre
    mc = means - centre
    chol = jnp.linalg.cholesky(covariances)                                   # (K, d, d)
    eye = jnp.broadcast_to(jnp.eye(d, dtype=covariances.dtype), covariances.shape)
    inv_chol = jax.scipy.linalg.solve_triangular(chol, eye, lower=True)      # (K, d, d) = L^-1
    prec = jnp.einsum("kji,kjl->kil", inv_chol, inv_chol)                     # (K, d, d) = Sigma^-1
    prec_mean = jnp.einsum("kij,kj->ki", prec, mc)                            # (K, d)
    const = jnp.einsum("ki,ki->k", prec_mean, mc)                             # (K,)
    outer = (xc[:, :, None] * xc[:, None, :]).reshape(x.shape[0], d * d)      # (T, d*d)
    maha = outer @ prec.reshape(K, d * d).T - 2.0 * (xc @ prec_mean.T) + const[None, :]   # (T, K)
    maha = jnp.maximum(maha, 0.0)                                             # round-off below 0
    logdet = 2.0 * jnp.sum(jnp.log(jnp.diagonal(chol, axis1=1, axis2=2)), axis=-1)  # (K,)
    return -0.5 * (maha + logdet[None, :] + d * jnp.log(2.0 * jnp.pi))


def stream_log_likelihoods(x, means, covariances, dims: tuple):
    """Log emissions of the columns ``dims`` only (e.g. speech-only synthesis). x: (T, D) -> (T, K).
    The covariance is block-diagonal over streams, so a sub-block is the stream's own Gaussian."""
    idx = jnp.asarray(dims)
    return gaussian_log_density(x[:, idx], means[:, idx], covariances[:, idx][:, :, idx])


def _lse(x, axis):
    """logsumexp that maps an all -inf slice to -inf without NaNs."""
    m = jnp.max(x, axis=axis, keepdims=True)
    m = jnp.where(jnp.isfinite(m), m, 0.0)
    return jnp.squeeze(m, axis) + jnp.log(jnp.sum(jnp.exp(x - m), axis=axis))


def _forward_step(carry, inp, log_initial, log_transitions):
    log_alpha_prev, ll = carry
    loglik_t, c_t, valid_t, first_t = inp
    log_pred = jnp.where(first_t, log_initial[c_t], _lse(log_alpha_prev[:, None] + log_transitions[c_t], axis=0))
    v = log_pred + loglik_t
    norm = _lse(v, axis=0)
    log_alpha = v - norm
    log_alpha = jnp.where(valid_t, log_alpha, log_alpha_prev)
    ll = jnp.where(valid_t, ll + norm, ll)
    return (log_alpha, ll), log_alpha


def _starts(T, resets):
    return jnp.arange(T) == 0 if resets is None else resets


def hmm_filter(initial, transitions, log_lik, constraints, length, resets=None):
    """Forward pass in log space. initial: (C, K); transitions: (C, K, K) (zeros allowed: -inf);
    log_lik: (T, K); constraints: (T,) int; length: () valid frames; resets: (T,) bool, the first
    frame of each sequence packed into this row (None: frame 0 only); the log-likelihood is then the
    sum over the packed sequences.
    Returns (log_likelihood, filtered (T, K), log filtered (T, K))."""
    T, K = log_lik.shape
    t = jnp.arange(T)
    step = partial(_forward_step, log_initial=jnp.log(initial), log_transitions=jnp.log(transitions))
    (_, ll), log_alpha = lax.scan(step, (jnp.zeros(K, log_lik.dtype), jnp.zeros((), log_lik.dtype)),
                                  (log_lik, constraints, t < length, _starts(T, resets)))
    return ll, jnp.exp(log_alpha), log_alpha


def _backward_step(carry, inp, log_transitions):
    log_beta, xi_sum = carry
    loglik_t, c_t, valid_t, start_t, log_alpha_prev = inp
    valid_t = valid_t & ~start_t       # no transition into the first frame of a (packed) sequence
    m = log_transitions[c_t] + (loglik_t + log_beta)[None, :]          # (K, K): i -> j
    row = jnp.max(m, axis=1)
    row = jnp.where(jnp.isfinite(row), row, 0.0)
    e = jnp.exp(m - row[:, None])                                       # the one K x K exp per frame
    log_beta_prev = row + jnp.log(jnp.sum(e, axis=1))
    # xi_ij = alpha_i a_ij b_j beta_j / sum(...) reuses e: its normalizer is lse_i(alpha_i + beta_prev_i)
    norm = _lse(log_alpha_prev + log_beta_prev, axis=0)
    scale = jnp.exp(jnp.where(jnp.isfinite(log_alpha_prev), log_alpha_prev + row - norm, -jnp.inf))
    xi = jnp.where(valid_t, e * scale[:, None], 0.0)
    mx = jnp.max(log_beta_prev)
    log_beta_prev = log_beta_prev - jnp.where(jnp.isfinite(mx), mx, 0.0)   # per-frame factor is free
    log_beta_prev = jnp.where(valid_t, log_beta_prev, jnp.zeros_like(log_beta_prev))
    xi_sum = xi_sum.at[c_t].add(xi)
    return (log_beta_prev, xi_sum), log_beta_prev


def hmm_posterior(initial, transitions, log_lik, constraints, length, resets=None) -> Posterior:
    """Forward-backward (smoother) in log space with expected transition counts per constraint.
    Shapes as :func:`hmm_filter`."""
    T, K = log_lik.shape
    C = transitions.shape[0]
    ll, alpha, log_alpha = hmm_filter(initial, transitions, log_lik, constraints, length, resets)
    starts = _starts(T, resets)
    t = jnp.arange(1, T)
    step = partial(_backward_step, log_transitions=jnp.log(transitions))
    init = (jnp.zeros(K, log_lik.dtype), jnp.zeros((C, K, K), log_lik.dtype))
    (_, xi_sum), log_betas = lax.scan(step, init, (log_lik[1:], constraints[1:], t < length, starts[1:], log_alpha[:-1]),
                                      reverse=True)
    log_beta = jnp.concatenate([log_betas, jnp.zeros((1, K), log_lik.dtype)], axis=0)
    lg = log_alpha + log_beta
    g = jnp.exp(lg - _lse(lg, axis=1)[:, None])
    g = jnp.where(jnp.isfinite(g), g, 0.0)                    # empty (length 0) sequences
    return Posterior(ll, alpha, g, xi_sum)


def _viterbi_step(delta, inp, log_transitions):
    loglik_t, c_t, valid_t, first_t, log_init_t = inp
    scores = delta[:, None] + log_transitions[c_t]         # (K, K)
    best = jnp.argmax(scores, axis=0)
    new = jnp.where(first_t, log_init_t, jnp.max(scores, axis=0)) + loglik_t
    K = delta.shape[0]
    new = jnp.where(valid_t, new, delta)
    ptr = jnp.where(valid_t & ~first_t, best, jnp.arange(K))
    return new, ptr


def hmm_viterbi(initial, transitions, log_lik, constraints, length):
    """Most likely state path (T,) int32 (padding frames repeat the last valid state) and its log
    joint probability."""
    T, K = log_lik.shape
    t = jnp.arange(T)
    log_a = jnp.log(transitions)            # structural zeros -> -inf
    log_pi = jnp.log(initial)[constraints]
    step = partial(_viterbi_step, log_transitions=log_a)
    delta, ptrs = lax.scan(step, jnp.full(K, -jnp.inf, log_lik.dtype),
                           (log_lik, constraints, t < length, t == 0, log_pi))
    last = jnp.argmax(delta).astype(jnp.int32)

    def back(state, ptr):
        prev = ptr[state].astype(jnp.int32)
        return prev, state

    _, path = lax.scan(back, last, ptrs, reverse=True)
    return path, jnp.max(delta)


STATE_MULTIPLE = 4


def pad_states(means, covariances, initial, transitions, multiple: int = STATE_MULTIPLE):
    """Pad a model's K states to a multiple of ``multiple`` with inert states (NumPy, before the
    kernels, so that models of nearby sizes share one compiled shape): initial probability 0 and no
    transition into them (log 0 = -inf, exact), a self-loop row, unit Gaussians. Every forward,
    backward and Viterbi message of an inert state is -inf, so the real states' posteriors, counts
    and log-likelihood are those of the unpadded model; slice the outputs back to K."""
    K = means.shape[0]
    Kp = -(-K // multiple) * multiple
    if Kp == K:
        return means, covariances, initial, transitions
    e = Kp - K
    D = means.shape[1]
    C = initial.shape[0]
    means = np.concatenate([np.asarray(means), np.zeros((e, D), np.asarray(means).dtype)])
    covariances = np.concatenate([np.asarray(covariances), np.broadcast_to(np.eye(D), (e, D, D))])
    initial = np.concatenate([np.asarray(initial), np.zeros((C, e))], axis=1)
    t = np.zeros((C, Kp, Kp))
    t[:, :K, :K] = transitions
    t[:, np.arange(K, Kp), np.arange(K, Kp)] = 1.0
    return means, covariances, initial, t


@partial(jax.jit, static_argnames=("dims",))
def batch_log_likelihoods(x, means, covariances, dims: tuple):
    """(B, T, D) -> (B, T, K) log emissions of the columns ``dims``."""
    return jax.vmap(lambda xb: stream_log_likelihoods(xb, means, covariances, dims))(x)


@partial(jax.jit, static_argnames=("dims",))
def batch_posterior(x, constraints, lengths, means, covariances, initial, transitions, dims: tuple, resets=None):
    """Smoother over a padded batch. x: (B, T, D); constraints: (B, T); lengths: (B,); resets: (B, T)
    bool or None (see :func:`hmm_filter`)."""
    ll = jax.vmap(lambda xb: stream_log_likelihoods(xb, means, covariances, dims))(x)
    if resets is None:
        return jax.vmap(hmm_posterior, in_axes=(None, None, 0, 0, 0))(initial, transitions, ll, constraints, lengths)
    return jax.vmap(hmm_posterior, in_axes=(None, None, 0, 0, 0, 0))(initial, transitions, ll, constraints, lengths,
                                                                      resets)


@partial(jax.jit, static_argnames=("dims",))
def batch_viterbi(x, constraints, lengths, means, covariances, initial, transitions, dims: tuple):
    ll = jax.vmap(lambda xb: stream_log_likelihoods(xb, means, covariances, dims))(x)
    return jax.vmap(hmm_viterbi, in_axes=(None, None, 0, 0, 0))(initial, transitions, ll, constraints, lengths)


@partial(jax.jit, static_argnames=("dims",))
def batch_filter(x, constraints, lengths, means, covariances, initial, transitions, dims: tuple):
    ll = jax.vmap(lambda xb: stream_log_likelihoods(xb, means, covariances, dims))(x)
    out = jax.vmap(hmm_filter, in_axes=(None, None, 0, 0, 0))(initial, transitions, ll, constraints, lengths)
    return out[0], out[1]


@partial(jax.jit, static_argnames=("dims",))
def batch_statistics(x, constraints, lengths, resets, shift, means, covariances, initial, transitions, dims: tuple):
    """E-step of EM over a padded (possibly packed: ``resets`` (B, T) bool marks the first frame of
    each sequence) batch, reduced on the device: (total log-likelihood, counts (K,),
    first (K, D) = sum_t gamma_t (x_t - shift), second (K, D, D) = sum_t gamma_t (x_t - shift)(x_t - shift)^T,
    initial counts (C, K) by first constraint, xi_sum (C, K, K)). ``shift`` (D,) centres the data
    (a global mean) so that float32 sums keep their precision."""
    post = batch_posterior(x, constraints, lengths, means, covariances, initial, transitions, dims, resets)
    B, T, D = x.shape
    K = means.shape[0]
    C = initial.shape[0]
    valid = (jnp.arange(T)[None, :] < lengths[:, None]).astype(x.dtype)
    g = (post.smoothed * valid[..., None]).reshape(B * T, K)
    xc = (x - shift).reshape(B * T, D)
    counts = jnp.sum(g, axis=0)
    first = g.T @ xc
    second = (g.T @ (xc[:, :, None] * xc[:, None, :]).reshape(B * T, D * D)).reshape(K, D, D)
    starts = (resets * valid).reshape(B * T)
    onehot = (constraints.reshape(B * T)[:, None] == jnp.arange(C)[None, :]).astype(x.dtype) * starts[:, None]
    init = onehot.T @ g                                                       # (C, K) over sequence starts
    return jnp.sum(post.log_likelihood), counts, first, second, init, jnp.sum(post.xi_sum, axis=0)
