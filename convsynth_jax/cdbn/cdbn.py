"""Training the jDBN baseline (Sec. VI) and the constrained DBN (Sec. VII).

* :func:`train_jdbn`: one ergodic DBN (C = 1), LBG or random initialization, EM with restarts.
* :func:`train_shared`: the "shared states" option of Sec. VII-B: one set of N states, a dense
  transition matrix per constraint (Eq. 5), EM on all data.
* :func:`train_cdbn`: the proposed model. (1) N states per constraint, trained (LBG + EM) on that
  constraint's frames only; (2) merging: for the states of each constraint in turn, the closest state
  (Gaussian KL divergence, Eq. 7) among the states of *other* constraints is merged with it when the
  divergence is below the threshold (1), becoming a shared state; (3) one new state shared by all
  constraints (initialized at the global Gaussian); (4) sparse per-constraint transition matrices:
  under constraint k the chain moves only among the states of k plus the shared state; (5) EM on all
  data, which keeps the structural zeros exactly zero.

Our reconstructions (the paper does not specify them): Eq. 7 as printed lacks the determinant and
inverse of the log term; we use the correct Gaussian KL, KL(P||Q) = 1/2 [tr(S_q^-1 S_p) + (m_q -
m_p)^T S_q^-1 (m_q - m_p) - d + ln(det S_q / det S_p)], on the joint (speech + motion) Gaussian, with
P the state of the constraint being processed. A merged state is the moment-matched Gaussian of the
two (weighted by their training occupancy); a state already holding the current constraint cannot
absorb a second of its states. When the constraint switches to k while the chain is in a state
outside k's set, the only allowed move is into the shared state ("a new state shared between all
the constraints to allow transition between the constraints"); from there the chain enters k's
states. Transition probabilities inside a constraint start from that constraint's own trained model.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from ..errors import CDBNError
from .em import Batch, e_step, fit_em, floor_covariance, make_batch
from .lbg import init_dbn
from .params import DBNModel, TrainParams, num_parameters

log = logging.getLogger(__name__)


def gaussian_kl(mean_p, cov_p, mean_q, cov_q) -> float:
    """KL(N_p || N_q) for full covariances (Eq. 7, with the log-determinant term the print lacks)."""
    d = len(mean_p)
    inv_q = np.linalg.inv(cov_q)
    r = mean_q - mean_p
    _, ld_q = np.linalg.slogdet(cov_q)
    _, ld_p = np.linalg.slogdet(cov_p)
    return float(0.5 * (np.trace(inv_q @ cov_p) + r @ inv_q @ r - d + ld_q - ld_p))


def transition_distance(a: np.ndarray, b: np.ndarray) -> float:
    """Eq. 8: d_inf(A, B) = max_i max_j |a_ij - b_ij|."""
    return float(np.max(np.abs(np.asarray(a) - np.asarray(b))))


@dataclass
class TrainedModel:
    """A trained model with its bookkeeping. owners: (K, C) bool, which constraints use each state
    (all True for the jDBN / shared model); log_likelihoods: EM trace (per frame); merges: the
    (constraint, state, KL) merges of Sec. VII-B (CDBN only)."""

    model: DBNModel
    owners: np.ndarray
    log_likelihoods: list
    kind: str
    merges: list = field(default_factory=list)
    transition_mask: np.ndarray | None = None   # the designed structure (None: dense)
    initial_mask: np.ndarray | None = None

    @property
    def num_parameters(self) -> int:
        """Free parameters of the designed structure (dense for jDBN / shared, the sparse masks of
        Sec. VII-B for the CDBN). Entries EM drove to exactly zero (float underflow of a tiny
        probability, which EM then keeps at zero) still count."""
        m = self.model
        if self.transition_mask is None:
            return num_parameters(m.num_states, len(m.speech_dims), len(m.motion_dims))
        return num_parameters(m.num_states, len(m.speech_dims), len(m.motion_dims),
                              self.transition_mask, self.initial_mask)


def _best_of_restarts(make_model, batch: Batch, params: TrainParams, rng: np.random.Generator):
    best = None
    for r in range(max(1, params.restarts)):
        start = make_model(np.random.default_rng(rng.integers(2 ** 31)))
        fit = fit_em(start, batch, params)
        log.info("EM restart %d: %d iterations, log-likelihood per frame %.4f", r, fit.iterations,
                 fit.log_likelihoods[-1])
        if best is None or fit.log_likelihoods[-1] > best.log_likelihoods[-1]:
            best = fit
    return best


def _frames(batch: Batch) -> np.ndarray:
    return batch.frames()[0]


def train_jdbn(sequences, num_states: int, speech_dims, motion_dims, params: TrainParams,
               feature_layout: tuple = (), init: str | None = None, max_length: int | None = 2048) -> TrainedModel:
    """The baseline jDBN (Sec. VI) on speech + motion sequences [(T_i, D)]; the constraint is ignored."""
    batch = make_batch(sequences, None, max_length=max_length, pack=True)
    x = _frames(batch)
    rng = np.random.default_rng(params.seed)
    fit = _best_of_restarts(lambda r: init_dbn(x, num_states, speech_dims, motion_dims, params, r, ("all",),
                                               init, feature_layout), batch, params, rng)
    return TrainedModel(fit.model, np.ones((num_states, 1), bool), fit.log_likelihoods, "jdbn")


def train_shared(sequences, constraints, num_states: int, speech_dims, motion_dims, params: TrainParams,
                 constraint_names: tuple, feature_layout: tuple = (), max_length: int | None = 2048) -> TrainedModel:
    """Option 1 of Sec. VII-B: N states shared by all constraints, one dense transition matrix per
    constraint."""
    batch = make_batch(sequences, constraints, max_length=max_length, pack=True)
    x = _frames(batch)
    rng = np.random.default_rng(params.seed)
    fit = _best_of_restarts(lambda r: init_dbn(x, num_states, speech_dims, motion_dims, params, r,
                                               tuple(constraint_names), None, feature_layout), batch, params, rng)
    return TrainedModel(fit.model, np.ones((num_states, len(constraint_names)), bool), fit.log_likelihoods, "shared")


def constraint_runs(sequences, constraints, code: int, min_frames: int = 2):
    """The maximal runs of frames with constraint ``code`` (each at least ``min_frames`` long)."""
    out = []
    for x, c in zip(sequences, constraints):
        c = np.asarray(c)
        edges = np.flatnonzero(np.diff(np.concatenate([[0], (c == code).astype(int), [0]])))
        for a, b in zip(edges[::2], edges[1::2]):
            if b - a >= min_frames:
                out.append(np.asarray(x)[a:b])
    return out


def _moment_match(w1, m1, s1, w2, m2, s2):
    w = w1 + w2
    m = (w1 * m1 + w2 * m2) / w
    s = (w1 * (s1 + np.outer(m1 - m, m1 - m)) + w2 * (s2 + np.outer(m2 - m, m2 - m))) / w
    return w, m, s


def merge_states(per_constraint: list[DBNModel], occupancy: list[np.ndarray], threshold: float):
    """Sec. VII-B merging. per_constraint[k]: the N-state model of constraint k; occupancy[k]: (N,)
    training frames per state. Returns (means (S, D), covs (S, D, D), owners (S, C) bool,
    origin: dict (k, i) -> merged state index, merges: list of (k, i, kl))."""
    C = len(per_constraint)
    groups = []  # dicts: weight, mean, cov, owners(set), members [(k, i)]
    for k, m in enumerate(per_constraint):
        for i in range(m.num_states):
            groups.append({"w": float(occupancy[k][i]) + 1e-6, "mean": m.means[i].copy(), "cov": m.covariances[i].copy(),
                           "owners": {k}, "members": [(k, i)]})
    merges = []
    for k in range(C):
        mine = [g for g in groups if g["members"][0][0] == k and g["owners"] == {k}]
        for g in mine:
            cands = [h for h in groups if h is not g and k not in h["owners"]]
            if not cands:
                continue
            kls = [gaussian_kl(g["mean"], g["cov"], h["mean"], h["cov"]) for h in cands]
            j = int(np.argmin(kls))
            if kls[j] < threshold:
                h = cands[j]
                h["w"], h["mean"], h["cov"] = _moment_match(h["w"], h["mean"], h["cov"], g["w"], g["mean"], g["cov"])
                h["owners"] |= {k}
                h["members"] += g["members"]
                groups.remove(g)
                merges.append((k, g["members"][0][1], float(kls[j])))
    means = np.stack([g["mean"] for g in groups])
    covs = np.stack([g["cov"] for g in groups])
    owners = np.zeros((len(groups), C), bool)
    origin = {}
    for s, g in enumerate(groups):
        for o in g["owners"]:
            owners[s, o] = True
        for mem in g["members"]:
            origin[mem] = s
    return means, covs, owners, origin, merges


def sparse_structure(owners: np.ndarray, shared: int | None):
    """Masks of the sparse model: transitions (C, K, K) and initial (C, K). Under constraint k the
    chain stays in S_k (states owned by k, including the shared one); from a state outside S_k it can
    only move into the shared state."""
    K, C = owners.shape
    tmask = np.zeros((C, K, K), bool)
    for k in range(C):
        s = owners[:, k]
        tmask[k][np.ix_(s, s)] = True
        if shared is not None:
            tmask[k][~s, shared] = True
        else:
            tmask[k][~s] = s[None, :]
    return tmask, owners.T.copy()


def train_cdbn(sequences, constraints, states_per_constraint: int | tuple, speech_dims, motion_dims, params: TrainParams,
               constraint_names: tuple, merge_threshold: float = 1.0, shared_state: bool = True,
               feature_layout: tuple = (), max_length: int | None = 2048) -> TrainedModel:
    """The proposed CDBN (Sec. VII). sequences: [(T_i, D)]; constraints: [(T_i,)] codes into
    ``constraint_names``; ``states_per_constraint``: N, or one N per constraint (ours: lets a system
    give a rare constraint fewer states)."""
    C = len(constraint_names)
    Ns = (tuple(int(v) for v in states_per_constraint) if isinstance(states_per_constraint, (tuple, list))
          else (int(states_per_constraint),) * C)
    rng = np.random.default_rng(params.seed)
    per, occ = [], []
    for k in range(C):
        runs = constraint_runs(sequences, constraints, k)
        n = sum(len(r) for r in runs)
        if n < params.min_frames_per_state * Ns[k]:
            raise CDBNError(f"too few frames per state for constraint {constraint_names[k]!r}: {n} frames for "
                            f"{Ns[k]} states (need {params.min_frames_per_state} per state)")
        sub = TrainParams(**{**params.__dict__, "seed": int(rng.integers(2 ** 31))})
        tm = train_jdbn(runs, Ns[k], speech_dims, motion_dims, sub, feature_layout,
                        max_length=max_length)
        b = make_batch(runs, None, max_length=max_length, pack=True)
        occ.append(e_step(tm.model, b).counts)
        per.append(tm.model)
    means, covs, owners, origin, merges = merge_states(per, occ, merge_threshold)
    log.info("CDBN: %s states per constraint -> %d after %d merges", Ns, len(means), len(merges))
    batch = make_batch(sequences, constraints, max_length=max_length, pack=True)
    x, _ = batch.frames()
    shared = None
    if shared_state:
        gm, gc = x.mean(0), np.cov(x.T)
        for dims in (speech_dims, motion_dims):
            ix = np.ix_(dims, dims)
            blk = floor_covariance(gc[ix], params.covariance_floor)[0]
            gc[ix] = blk
        sd, md = list(speech_dims), list(motion_dims)
        gc[np.ix_(sd, md)] = 0.0
        gc[np.ix_(md, sd)] = 0.0
        means = np.concatenate([means, gm[None]])
        covs = np.concatenate([covs, gc[None]])
        owners = np.concatenate([owners, np.ones((1, C), bool)])
        shared = len(means) - 1
    K = len(means)
    tmask, imask = sparse_structure(owners, shared)
    trans = np.zeros((C, K, K))
    eps = 0.02
    for k in range(C):
        pk = per[k]
        for i in range(pk.num_states):
            for j in range(pk.num_states):
                trans[k, origin[(k, i)], origin[(k, j)]] += pk.transitions[0, i, j]
        if shared is not None:
            trans[k][owners[:, k], shared] += eps
            trans[k][shared][owners[:, k]] = 1.0
        trans[k] = np.where(tmask[k], trans[k] + 1e-3, 0.0)
    trans /= trans.sum(-1, keepdims=True)
    init = imask / imask.sum(-1, keepdims=True)
    model = DBNModel(means, covs, init, trans, tuple(speech_dims), tuple(motion_dims), tuple(constraint_names),
                     tuple(feature_layout))
    fit = fit_em(model, batch, params)
    return TrainedModel(fit.model, owners, fit.log_likelihoods, "cdbn", merges, tmask, imask)
