"""A planted constrained DBN and a sampler from it, for recovery tests and benchmarks.

:func:`planted_cdbn` builds the structure :func:`~.cdbn.train_cdbn` learns: N states per constraint,
some states shared by two constraints, one state shared by all (entered when the constraint changes),
sparse per-constraint transition matrices and block-diagonal (speech, motion) Gaussians whose means
are well separated. :func:`sample` draws turns whose constraint sequence is a run of segments.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .cdbn import sparse_structure
from .params import DBNModel


class Sample(NamedTuple):
    observations: list      # [(T_i, D)]
    constraints: list       # [(T_i,)] int
    states: list            # [(T_i,)] int


def planted_cdbn(rng: np.random.Generator, num_constraints: int = 3, states_per_constraint: int = 4,
                 speech_dim: int = 6, motion_dim: int = 3, shared_pairs: int = 1, separation: float = 4.0,
                 self_transition: tuple = (0.85, 0.95)) -> tuple[DBNModel, np.ndarray]:
    """(model, owners (K, C)). The first ``shared_pairs`` constraint pairs (0,1), (1,2) ... share one
    state; the last state is shared by all constraints."""
    C, N = num_constraints, states_per_constraint
    owners = []
    for k in range(C):
        for i in range(N):
            if i == 0 and 0 < k <= shared_pairs:
                owners[-1][k] = True      # state 0 of constraint k is the last state of constraint k-1
                continue
            row = np.zeros(C, bool)
            row[k] = True
            owners.append(row)
    owners.append(np.ones(C, bool))
    owners = np.array(owners)
    K = len(owners)
    D = speech_dim + motion_dim
    # means on a jittered grid so that every pair is at least ``separation`` SDs apart in some dims
    means = np.zeros((K, D))                      # the shared state sits at the origin
    for s in range(K - 1):                         # rejection: every pair at least ``separation`` apart
        while True:
            m = rng.normal(0, 1, D)
            m *= separation * rng.uniform(1.0, 1.6) / np.linalg.norm(m)
            if all(np.linalg.norm(m - means[o]) >= separation for o in range(s)):
                means[s] = m
                break
    covs = np.zeros((K, D, D))
    for s in range(K):
        for dims in (range(speech_dim), range(speech_dim, D)):
            a = rng.normal(0, 0.3, (len(dims), len(dims)))
            covs[s][np.ix_(dims, dims)] = a @ a.T + 0.4 * np.eye(len(dims))
    covs[-1] *= 4.0   # the shared state is broad
    tmask, imask = sparse_structure(owners, K - 1)
    trans = np.zeros((C, K, K))
    for k in range(C):
        for i in range(K):
            allowed = np.flatnonzero(tmask[k, i])
            if len(allowed) == 1:
                trans[k, i, allowed[0]] = 1.0
                continue
            p = rng.dirichlet(np.ones(len(allowed) - 1))
            stay = rng.uniform(*self_transition)
            others = [a for a in allowed if a != i]
            if i == K - 1:                          # the shared state is a brief passage
                trans[k, i, i] = 0.3
                trans[k, i, others] = 0.7 * p
            elif i in allowed:
                trans[k, i, i] = stay
                trans[k, i, others] = (1 - stay) * p
            else:
                trans[k, i, allowed] = rng.dirichlet(np.ones(len(allowed)))
    init = imask / imask.sum(-1, keepdims=True)
    model = DBNModel(means, covs, init, trans, tuple(range(speech_dim)), tuple(range(speech_dim, D)),
                     tuple(f"c{k}" for k in range(C)))
    return model, owners


def constraint_sequence(rng: np.random.Generator, length: int, num_constraints: int,
                        segment: tuple = (80, 250)) -> np.ndarray:
    c = np.empty(length, np.int32)
    t, prev = 0, -1
    while t < length:
        k = int(rng.integers(num_constraints))
        if k == prev:
            k = (k + 1) % num_constraints
        n = int(rng.integers(*segment))
        c[t:t + n] = k
        t += n
        prev = k
    return c


def sample(model: DBNModel, rng: np.random.Generator, num_sequences: int, length: int,
           segment: tuple = (80, 250)) -> Sample:
    """Turns of ``length`` frames from the planted model (constraints drawn as random segments)."""
    K, D = model.means.shape
    chol = np.linalg.cholesky(model.covariances)
    xs, cs, qs = [], [], []
    for _ in range(num_sequences):
        c = constraint_sequence(rng, length, model.num_constraints, segment)
        q = np.empty(length, np.int64)
        q[0] = rng.choice(K, p=model.initial[c[0]])
        u = rng.random(length)
        cum = np.cumsum(model.transitions, axis=-1)
        for t in range(1, length):
            q[t] = min(int(np.searchsorted(cum[c[t], q[t - 1]], u[t])), K - 1)
        z = rng.standard_normal((length, D))
        x = model.means[q] + np.einsum("tij,tj->ti", chol[q], z)
        xs.append(x)
        cs.append(c)
        qs.append(q)
    return Sample(xs, cs, qs)


def match_states(true: DBNModel, est: DBNModel) -> np.ndarray:
    """perm (K_true,): the estimated state matched to each planted state (Hungarian assignment on the
    mean distance in units of the planted SDs; -1 where the estimate has fewer states)."""
    from scipy.optimize import linear_sum_assignment

    sd = np.sqrt(np.diagonal(true.covariances, axis1=1, axis2=2))          # (Kt, D)
    cost = np.abs(true.means[:, None, :] - est.means[None, :, :]) / sd[:, None, :]
    cost = cost.max(-1)                                                     # (Kt, Ke) worst dimension
    r, c = linear_sum_assignment(cost)
    perm = np.full(true.num_states, -1)
    perm[r] = c
    return perm


def recovery_report(true: DBNModel, est: DBNModel, sd_tolerance: float = 0.25) -> dict:
    """Fraction of planted states whose mean is recovered within ``sd_tolerance`` planted SDs (every
    dimension), and the L-inf transition error over matched states (Eq. 8 per constraint, max)."""
    perm = match_states(true, est)
    sd = np.sqrt(np.diagonal(true.covariances, axis1=1, axis2=2))
    ok = np.zeros(true.num_states, bool)
    for i, j in enumerate(perm):
        if j >= 0:
            ok[i] = np.all(np.abs(est.means[j] - true.means[i]) <= sd_tolerance * sd[i])
    m = perm >= 0
    idx = perm[m]
    errs = [float(np.max(np.abs(est.transitions[k][np.ix_(idx, idx)] - true.transitions[k][np.ix_(m, m)])))
            for k in range(true.num_constraints)]
    return {"states_true": true.num_states, "states_estimated": est.num_states,
            "states_recovered": float(ok.mean()), "recovered": ok.tolist(),
            "transition_linf": max(errs), "transition_linf_per_constraint": errs, "perm": perm.tolist()}
