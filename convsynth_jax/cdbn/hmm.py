"""HMM inference for the (constrained) DBN in JAX: forward filter, backward pass, smoother, expected
transition counts and Viterbi; the recursions are ``lax.scan`` over a named ``_step`` (dynamax
style), the expected transition counts are summed after them, in parallel over frames.

The constraint sequence c_t selects the transition matrix at every frame (Eq. 5:
a^k_ij = P(q_t = j | q_{t-1} = i, C_t = k)) and the initial distribution at the first frame.
The messages are carried in log space: structural zeros of the transition matrices are -inf and stay
exact, and no frame underflows even when the emissions of every reachable state are thousands of
nats below an unreachable one (a scaled float32 recursion, tried first, failed exactly there on
concatenated held-out turns). The sum over the previous (next) state is, in the smoother of a
batch, one scaled product in linear space with a bound on what it leaves out, and the exact
log-sum-exp at the frames where that bound could matter (:func:`_fast_log_products`); the filter and
Viterbi take the log-sum-exp (max) at every frame. The forward message is
renormalized per frame (the normalizers sum to the log-likelihood); the backward message is scaled
per frame so that sum_i alpha_{t-1,i} beta_{t-1,i} = 1 (it is defined up to a per-frame factor; this
one keeps the states that alpha can reach near 0 even when unreachable ones, such as the inert
padding states, have far larger beta), and that factor normalizes the expected transitions.

Primitives work on one sequence of ``T`` frames of which the first ``length`` are valid (the rest
is padding, so that batches of sequences share one compiled shape); batch them with ``jax.vmap``.
The smoother is written for a batch (:func:`_batch_smoother`: each scan step takes one frame of
every row, so that a frame at risk switches the whole batch to the exact step with one ``lax.cond``,
which ``vmap`` would turn into computing both branches); :func:`_smoother` is its batch of one.
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
    expands into the products x_i x_j, i <= j (T, d(d+1)/2) against P (off-diagonal entries twice),
    minus 2 x^T P mu, plus mu^T P mu,
    so no (K, T, d) array is formed (that array's memory traffic was most of the E-step on the CPU).
    Everything is centred first on the mean of the state means, which keeps the expansion's terms
    near the size of the result (checked against the float64 reference, also in float32)."""
    d = x.shape[-1]
    centre = jnp.mean(means, axis=0)
    xc = x - centre
    mc = means - centre
    chol = jnp.linalg.cholesky(covariances)                                   # (K, d, d)
    eye = jnp.broadcast_to(jnp.eye(d, dtype=covariances.dtype), covariances.shape)
    inv_chol = jax.scipy.linalg.solve_triangular(chol, eye, lower=True)      # (K, d, d) = L^-1
    prec = jnp.einsum("kji,kjl->kil", inv_chol, inv_chol)                     # (K, d, d) = Sigma^-1
    prec_mean = jnp.einsum("kij,kj->ki", prec, mc)                            # (K, d)
    const = jnp.einsum("ki,ki->k", prec_mean, mc)                             # (K,)
    iu, ju = np.triu_indices(d)                                               # the d(d+1)/2 distinct products
    outer = xc[:, iu] * xc[:, ju]                                             # (T, d(d+1)/2)
    w = jnp.where(iu == ju, 1.0, 2.0).astype(prec.dtype)                      # off-diagonal terms twice
    maha = outer @ (prec[:, iu, ju] * w).T - 2.0 * (xc @ prec_mean.T) + const[None, :]   # (T, K)
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


class TransitionTerms(NamedTuple):
    """What the expected transition into frame t needs, per frame (N frames: one sequence, or a batch
    flattened): log_alpha_prev (N, K) log alpha_{t-1} (filtered); log_obs (N, K) log b_j(x_t) +
    log beta_tj; log_norm (N,) log sum_ij alpha_{t-1,i} a^c_ij b_j(x_t) beta_tj (beta in the same
    per-frame scale); log_gamma (N, K) log P(q_t = j | x); constraints (N,) c_t; into (N,) bool,
    frames with a transition into them (valid and not the first frame of a sequence)."""

    log_alpha_prev: jnp.ndarray
    log_obs: jnp.ndarray
    log_norm: jnp.ndarray
    log_gamma: jnp.ndarray
    constraints: jnp.ndarray
    into: jnp.ndarray


XI_FAST_SPAN = 60.0     # largest log factor s_t of a frame summed by the matrix product
XI_NEGLIGIBLE = -40.0   # log P(q_t = j | x) below which state j's transitions into t are left out of it
XI_EXACT_BLOCK = 64     # frames per block of the exact log-space sum


def expected_transitions(terms: TransitionTerms, transitions, fast_span: float = XI_FAST_SPAN):
    """Expected transition counts per constraint, summed in parallel over frames after the scans:
    xi_sum[c]_ij = sum over frames t with c_t = c and into_t of
    exp(log_alpha_prev_ti + log a^c_ij + log_obs_tj - log_norm_t)   (= P(q_{t-1}=i, q_t=j | x)).
    terms: :class:`TransitionTerms` of N frames; transitions: (C, K, K) (zeros: structural);
    fast_span: see below (-inf: every frame by the exact log-space sum) -> (C, K, K).

    Most frames factorize: xi_t = a^c * (P_t R_t^T) with P_ti = alpha_{t-1,i} (<= 1) and
    R_tj = b_j beta_tj / norm_t = gamma_tj / pred_tj, so the sum over frames is one matrix product
    per constraint, with 2K exponentials per frame instead of K x K. Scaled as e^{s_t/2} P_t and
    e^{-s_t/2} R_t, s_t = max_i log P_ti + max_j log R_tj, both factors lie in [0, e^{s_t/2}] and
    every term above e^{-30} needs factors >= e^{-s_t/2-30}: for s_t <= fast_span (60) nothing that
    matters under- or overflows in float32. States j with gamma_tj < e^-40 (all their xi_tij are
    smaller) are left out of R_t, so that states that alpha_{t-1} cannot reach (pred_tj = 0, e.g. the
    inert padding states) do not set s_t. A larger s_t means that alpha_{t-1} and gamma_t sit on
    states with (near) structural zeros between them (a sparse CDBN on concatenated turns); those
    frames, usually none, are summed exactly in log space, XI_EXACT_BLOCK at a time (a loop of zero
    iterations when there are none). Structural zeros get exactly 0 either way."""
    C = transitions.shape[0]
    la, constraints, into = terms.log_alpha_prev, terms.constraints, terms.into
    dt = la.dtype
    log_r = jnp.where(terms.log_gamma >= XI_NEGLIGIBLE, terms.log_obs - terms.log_norm[:, None], -jnp.inf)  # (N, K)
    m1 = jnp.max(la, axis=1)
    m1 = jnp.where(jnp.isfinite(m1), m1, 0.0)
    m2 = jnp.max(log_r, axis=1)
    m2 = jnp.where(jnp.isfinite(m2), m2, 0.0)
    span = m1 + m2                                                              # (N,) s_t
    fast = into & (span <= fast_span)
    h = jnp.where(fast, 0.5 * span, 0.0)[:, None]
    p = jnp.where(fast[:, None], jnp.exp(la - m1[:, None] + h), 0.0)          # (N, K) e^{s/2} P_t / max P_t
    r = jnp.exp(log_r - m2[:, None] + h)                                        # (N, K) e^{s/2} R_t / max R_t
    s = jnp.stack([jnp.where((constraints == c)[:, None], p, 0.0).T @ r for c in range(C)])   # (C, K, K)
    xi = jnp.where(transitions > 0, transitions * s, 0.0)
    # the other frames exactly, in blocks of M gathered by their rank among them
    slow = into & ~fast
    rank = jnp.cumsum(slow) - 1
    n_slow = rank[-1] + 1
    M = XI_EXACT_BLOCK
    log_a = jnp.log(transitions)
    frame = jnp.arange(slow.shape[0])

    def block(k, acc):
        here = slow & (rank // M == k)
        idx = jnp.zeros(M, frame.dtype).at[jnp.where(here, rank - k * M, M)].set(frame, mode="drop")   # (M,)
        ok = k * M + jnp.arange(M) < n_slow
        c = constraints[idx]
        e = jnp.exp(la[idx][:, :, None] + log_a[c] + terms.log_obs[idx][:, None, :]
                    - terms.log_norm[idx][:, None, None])                       # (M, K, K) xi_t
        e = jnp.where(ok[:, None, None], e, 0.0)
        onehot = (c[:, None] == jnp.arange(C)[None, :]).astype(dt)
        return acc + jnp.einsum("mc,mij->cij", onehot, e)

    return lax.fori_loop(0, (n_slow + M - 1) // M, block, xi)


MESSAGE_CUT = 40.0      # log units: states this far below the best (and smaller a_ij) are left out of the fast products
MESSAGE_MARGIN = 20.0   # log units: what they could add must stay below e^-MARGIN of every entry


def _select_constraint(per_c, constraints):
    """(B, C, K) -> (B, K): row b's entry for its constraint c_b."""
    if per_c.shape[1] == 1:
        return per_c[:, 0]
    return jnp.take_along_axis(per_c, constraints[:, None, None], axis=1)[:, 0]


class FastMatrices(NamedTuple):
    """The transition matrices as the fast products use them: big (C, K, K) the entries >= e^-CUT
    (the rest 0); bound (C, 2K, K) forward / (C, K, 2K) backward: [a; 1(0 < a < e^-CUT)] stacked
    along the summed index, for the bound on what the products leave out."""

    big: jnp.ndarray
    bound: jnp.ndarray


def _fast_matrices(transitions, transpose: bool) -> FastMatrices:
    small = jnp.exp(-MESSAGE_CUT).astype(transitions.dtype)
    big = jnp.where(transitions >= small, transitions, 0.0)
    tiny = ((transitions > 0) & (transitions < small)).astype(transitions.dtype)
    return FastMatrices(big, jnp.concatenate([transitions, tiny], axis=2 if transpose else 1))


def _fast_log_products(log_v, mats: FastMatrices, constraints, transpose: bool):
    """Log-space matrix-vector products of a batch by one scaled product in linear space:
    out_bj = log sum_i exp(log_v_bi) a^{c_b}_ij (forward; transpose: out_bi = log sum_j a^{c_b}_ij
    exp(log_v_bj), backward). log_v: (B, K); mats: :func:`_fast_matrices` of transitions (C, K, K)
    (zeros: structural); constraints: (B,) -> (out (B, K), at_risk (B,) bool).

    Each row is scaled by its largest entry m_b; entries more than MESSAGE_CUT (40) below it are left
    out, and so are transition probabilities below e^-CUT, so that no product that is kept falls
    below e^-80 (float32 underflows at e^-87). Each term left out is below e^{m_b - CUT}, so what they
    would have added to out_bj is at most e^{m_b - CUT} r_bj, r_bj = sum over the left-out entries i
    of a_ij plus the number of kept entries i with 0 < a_ij < e^-CUT (one more product, with [left
    out, kept] against [a; 1(tiny a)]). A row is at risk when that bound reaches e^-MARGIN of an
    entry (e.g. a structural-zero pattern that routes all the mass of a frame through a state e^-300
    below the best); the caller then takes the exact log-space step for that frame. Otherwise every
    entry is within e^-MARGIN (relative) of the exact sum, below float32 round-off."""
    m = jnp.max(log_v, axis=1, keepdims=True)
    m = jnp.where(jnp.isfinite(m), m, 0.0)
    rel = log_v - m
    keep = rel >= -MESSAGE_CUT
    w = jnp.where(keep, jnp.exp(jnp.where(keep, rel, 0.0)), 0.0)                 # (B, K) in [e^-CUT, 1]
    left_out = (jnp.isfinite(log_v) & ~keep).astype(w.dtype)
    marks = jnp.concatenate([left_out, keep.astype(w.dtype)], axis=1)            # (B, 2K)
    spec = "bj,cij->bci" if transpose else "bi,cij->bcj"
    lin = _select_constraint(jnp.einsum(spec, w, mats.big), constraints)
    reach = _select_constraint(jnp.einsum(spec, marks, mats.bound), constraints)
    at_risk = jnp.any(reach * np.exp(-MESSAGE_CUT + MESSAGE_MARGIN) > lin, axis=1)
    return m + jnp.log(lin), at_risk


def _exact_log_products(log_v, log_transitions, constraints, transpose: bool):
    """The same products exactly, by log-sum-exp over K x K terms per row (the slow path)."""
    la = log_transitions[constraints]                                            # (B, K, K)
    if transpose:
        return _lse(la + log_v[:, None, :], axis=2)
    return _lse(log_v[:, :, None] + la, axis=1)


def _log_products(log_v, mats, log_transitions, constraints, needed, transpose: bool, products: str):
    """The products of one frame and whether any row whose product is ``needed`` (B,) bool was at
    risk. ``products``: "fast" (:func:`_fast_log_products` only), "exact" (:func:`_exact_log_products`
    only) or "adaptive" (the exact ones for the whole batch at a frame where a needed row is at risk,
    the fast ones elsewhere)."""
    if products == "exact":
        return _exact_log_products(log_v, log_transitions, constraints, transpose), jnp.zeros((), bool)
    fast, at_risk = _fast_log_products(log_v, mats, constraints, transpose)
    risk = jnp.any(at_risk & needed)
    if products == "fast":
        return fast, risk
    out = lax.cond(risk, lambda: _exact_log_products(log_v, log_transitions, constraints, transpose), lambda: fast)
    return out, risk


def _batch_forward_step(carry, inp, log_initial, mats, log_transitions, products):
    log_alpha_prev, ll = carry                                                   # (B, K), (B,)
    loglik_t, c_t, valid_t, first_t = inp                                        # (B, K), (B,), (B,), (B,)
    pred, risk = _log_products(log_alpha_prev, mats, log_transitions, c_t, valid_t & ~first_t, False, products)
    log_pred = jnp.where(first_t[:, None], log_initial[c_t], pred)
    v = log_pred + loglik_t
    norm = _lse(v, axis=1)
    log_alpha = jnp.where(valid_t[:, None], v - norm[:, None], log_alpha_prev)
    ll = jnp.where(valid_t, ll + norm, ll)
    return (log_alpha, ll), (log_alpha, risk)


def _batch_backward_step(log_beta, inp, mats, log_transitions, products):
    loglik_t, c_t, into_t, log_alpha_prev, log_alpha_t = inp   # into_t: a transition into t exists (valid, not a start)
    # states that alpha_t cannot reach (exact zeros, e.g. inert padding states) are left out: for every
    # state i that alpha_{t-1} reaches, a_ij b_j = 0 for them, and their beta (often far larger than
    # the reachable states', which would set the scale of the fast product) multiplies alpha_t = 0
    v = jnp.where(jnp.isfinite(log_alpha_t), loglik_t + log_beta, -jnp.inf)
    ub, risk = _log_products(v, mats, log_transitions, c_t, into_t, True, products)
    norm = _lse(log_alpha_prev + ub, axis=1)       # sum_ij alpha_{t-1,i} a_ij b_j beta_j: the transition's normalizer
    norm = jnp.where(into_t & jnp.isfinite(norm), norm, 0.0)
    log_beta_prev = jnp.where(into_t[:, None], ub - norm[:, None], 0.0)   # sum_i alpha_{t-1,i} beta_{t-1,i} = 1
    return log_beta_prev, (log_beta_prev, norm, risk)


def _batch_scans(initial, transitions, log_lik, constraints, lengths, resets, products: str):
    """:func:`_batch_smoother` with one kind of products; also returns whether any frame was at risk."""
    B, T, K = log_lik.shape
    dt = log_lik.dtype
    t = jnp.arange(T)
    starts = jnp.broadcast_to(t == 0, (B, T)) if resets is None else resets
    valid = t[None, :] < lengths[:, None]
    log_a = jnp.log(transitions)
    tm = lambda a: jnp.swapaxes(a, 0, 1)                                         # (B, T, ...) <-> (T, B, ...)
    fwd = partial(_batch_forward_step, log_initial=jnp.log(initial), mats=_fast_matrices(transitions, False),
                  log_transitions=log_a, products=products)
    (_, ll), (log_alpha, risk_f) = lax.scan(fwd, (jnp.zeros((B, K), dt), jnp.zeros(B, dt)),
                                            (tm(log_lik), tm(constraints), tm(valid), tm(starts)))  # (T, B, K)
    into = valid & ~starts
    bwd = partial(_batch_backward_step, mats=_fast_matrices(transitions, True), log_transitions=log_a,
                  products=products)
    _, (log_betas, log_norms, risk_b) = lax.scan(bwd, jnp.zeros((B, K), dt),
                                                 (tm(log_lik)[1:], tm(constraints)[1:], tm(into)[1:], log_alpha[:-1], log_alpha[1:]),
                                                 reverse=True)
    log_alpha = tm(log_alpha)                                                    # (B, T, K)
    log_beta = jnp.concatenate([tm(log_betas), jnp.zeros((B, 1, K), dt)], axis=1)   # (B, T, K), scaled
    lg = log_alpha + log_beta
    norm = _lse(lg, axis=2)
    log_gamma = lg - norm[..., None]
    g = jnp.exp(log_gamma)
    g = jnp.where(jnp.isfinite(g), g, 0.0)                    # empty (length 0) rows
    log_norm = jnp.concatenate([jnp.zeros((B, 1), dt), tm(log_norms)], axis=1)   # (B, T) of the transition into t
    log_alpha_prev = jnp.concatenate([log_alpha[:, :1], log_alpha[:, :-1]], axis=1)
    terms = TransitionTerms(log_alpha_prev, log_lik + log_beta, log_norm, log_gamma, constraints, into)
    return (ll, jnp.exp(log_alpha), g, terms), jnp.any(risk_f) | jnp.any(risk_b)


EXACT_BELOW = 1024      # B x K x K below which a scan step takes the exact products (small models, one row)


def _batch_smoother(initial, transitions, log_lik, constraints, lengths, resets, products: str = "auto"):
    """Both scans over a batch of B rows at once (each scan step takes the frame of every row) in log
    space, the sums over the previous / next state by :func:`_fast_log_products`, exactly in log space
    at a frame where those are at risk. initial: (C, K); transitions: (C, K, K) (zeros: structural);
    log_lik: (B, T, K); constraints: (B, T); lengths: (B,); resets: (B, T) bool or None (frame 0
    only); products: see :func:`_log_products` ("exact" is the all-log-space kernel of old); "auto":
    "exact" when a step holds fewer than EXACT_BELOW terms B x K x K (there the K x K exponentials cost
    less than the fixed cost of the fast step's extra operations), "adaptive" otherwise.
    Returns (log_likelihood (B,), filtered (B, T, K), smoothed (B, T, K), :class:`TransitionTerms`
    (B, T, ...))."""
    if products == "auto":
        B, _, K = log_lik.shape
        products = "exact" if B * K * K < EXACT_BELOW else "adaptive"
    return _batch_scans(initial, transitions, log_lik, constraints, lengths, resets, products)[0]


def _smoother(initial, transitions, log_lik, constraints, length, resets):
    """Both scans of one sequence (shapes as :func:`hmm_filter`): :func:`_batch_smoother` on a batch
    of one. Returns (log_likelihood, filtered (T, K), smoothed (T, K), :class:`TransitionTerms` of its
    T frames (frame 0: into = False))."""
    out = _batch_smoother(initial, transitions, log_lik[None], constraints[None], jnp.asarray(length)[None],
                          None if resets is None else resets[None])
    return jax.tree_util.tree_map(lambda a: a[0], out)


def hmm_posterior(initial, transitions, log_lik, constraints, length, resets=None) -> Posterior:
    """Forward-backward (smoother) in log space with expected transition counts per constraint.
    Shapes as :func:`hmm_filter`. The backward scan carries log beta only; the expected transitions
    are summed afterwards, in parallel over frames (:func:`expected_transitions`)."""
    ll, alpha, g, terms = _smoother(initial, transitions, log_lik, constraints, length, resets)
    return Posterior(ll, alpha, g, expected_transitions(terms, transitions))


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


def _batch_emissions(x, means, covariances, dims: tuple):
    """(B, T, D) -> (B, T, K) log emissions of the columns ``dims`` (inside the batch kernels)."""
    return jax.vmap(lambda xb: stream_log_likelihoods(xb, means, covariances, dims))(x)


batch_log_likelihoods = partial(jax.jit, static_argnames=("dims",))(_batch_emissions)


@partial(jax.jit, static_argnames=("dims",))
def batch_smoothed(x, constraints, lengths, means, covariances, initial, transitions, dims: tuple):
    """Smoothed posteriors (B, T, K) of a padded batch: both scans, without the expected transition
    counts (synthesis needs gamma only). Shapes as :func:`batch_posterior`."""
    ll = _batch_emissions(x, means, covariances, dims)
    return _batch_smoother(initial, transitions, ll, constraints, lengths, None)[2]


@partial(jax.jit, static_argnames=("dims",))
def batch_posterior(x, constraints, lengths, means, covariances, initial, transitions, dims: tuple, resets=None):
    """Smoother over a padded batch. x: (B, T, D); constraints: (B, T); lengths: (B,); resets: (B, T)
    bool or None (see :func:`hmm_filter`). Returns a :class:`Posterior` with a leading batch axis."""
    ll = _batch_emissions(x, means, covariances, dims)
    lls, alpha, g, terms = _batch_smoother(initial, transitions, ll, constraints, lengths, resets)
    xi = jax.vmap(expected_transitions, in_axes=(0, None))(terms, transitions)
    return Posterior(lls, alpha, g, xi)


@partial(jax.jit, static_argnames=("dims",))
def batch_viterbi(x, constraints, lengths, means, covariances, initial, transitions, dims: tuple):
    ll = _batch_emissions(x, means, covariances, dims)
    return jax.vmap(hmm_viterbi, in_axes=(None, None, 0, 0, 0))(initial, transitions, ll, constraints, lengths)


@partial(jax.jit, static_argnames=("dims",))
def batch_filter(x, constraints, lengths, means, covariances, initial, transitions, dims: tuple):
    ll = _batch_emissions(x, means, covariances, dims)
    out = jax.vmap(hmm_filter, in_axes=(None, None, 0, 0, 0))(initial, transitions, ll, constraints, lengths)
    return out[0], out[1]


@partial(jax.jit, static_argnames=("dims",))
def batch_statistics(x, constraints, lengths, resets, shift, means, covariances, initial, transitions, dims: tuple):
    """E-step of EM over a padded (possibly packed: ``resets`` (B, T) bool marks the first frame of
    each sequence) batch, reduced on the device: (total log-likelihood, counts (K,),
    first (K, D) = sum_t gamma_t (x_t - shift), second (K, D, D) = sum_t gamma_t (x_t - shift)(x_t - shift)^T,
    initial counts (C, K) by first constraint, xi_sum (C, K, K)). ``shift`` (D,) centres the data
    (a global mean) so that float32 sums keep their precision."""
    ll = _batch_emissions(x, means, covariances, dims)
    lls, _, smoothed, terms = _batch_smoother(initial, transitions, ll, constraints, lengths, resets)
    B, T, D = x.shape
    K = means.shape[0]
    C = initial.shape[0]
    flat = jax.tree_util.tree_map(lambda a: a.reshape((B * T,) + a.shape[2:]), terms)
    xi = expected_transitions(flat, transitions)                              # all frames at once
    valid = (jnp.arange(T)[None, :] < lengths[:, None]).astype(x.dtype)
    g = (smoothed * valid[..., None]).reshape(B * T, K)
    xc = (x - shift).reshape(B * T, D)
    counts = jnp.sum(g, axis=0)
    first = g.T @ xc
    iu, ju = np.triu_indices(D)
    tri = g.T @ (xc[:, iu] * xc[:, ju])                                       # (K, D(D+1)/2): i <= j only
    second = jnp.zeros((K, D, D), x.dtype).at[:, iu, ju].set(tri).at[:, ju, iu].set(tri)
    starts = (resets * valid).reshape(B * T)
    onehot = (constraints.reshape(B * T)[:, None] == jnp.arange(C)[None, :]).astype(x.dtype) * starts[:, None]
    init = onehot.T @ g                                                       # (C, K) over sequence starts
    return jnp.sum(lls), counts, first, second, init, xi
