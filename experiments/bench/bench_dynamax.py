"""Side by side with dynamax: one EM iteration of our CDBN EM against dynamax's ``fit_em`` on the same
data, in one process, with the two implementations' repeats interleaved so that machine load hits
both alike (writes experiments/results/bench_dynamax.json + manifest).

Problem (the size of bench_cdbn.py's EM benchmark): 100k frames as 50 sequences of 2,000, 9
dimensions, 41 states, full covariances, float32 kernels.

* jDBN: one dense transition matrix. dynamax: ``GaussianHMM.fit_em``.
* CDBN: three constraint-indexed transition matrices with the structural zeros of Sec. VII-B
  (``cdbn.sparse_structure``: one state shared by all constraints, one by two, 13 of each
  constraint's own; from outside S_k only into the shared state), constraint runs of 80-250 frames
  (``sampler.constraint_sequence``). dynamax has no constraint-indexed transitions; the model a
  dynamax user would write is a ``dynamax.HMM`` with its Gaussian emission component and a transition
  component whose matrices are indexed by the per-frame constraint (the inputs): dynamax's documented
  time-varying transition matrices (T-1, K, K), expected counts summed per constraint, an M-step that
  keeps the zeros (:class:`ConstrainedTransitions` below).

Timing: dynamax's ``fit_em`` runs its iterations as one jitted ``lax.scan`` whose loop it jits anew
at every call (about 10 s of compiling here, whose noise swamps the (5 - 2 iterations) / 3
difference under load); an iteration of dynamax is therefore the body of that loop (dynamax's own
vmapped ``e_step``, ``log_prior`` and ``m_step``), jitted once. Ours is ``e_step`` + ``m_step`` (the
E-step jitted, the M-step float64 NumPy on the host, as our ``fit_em`` runs it). Both are called
once before timing (compile excluded). Each repeat times three iterations of each, alternating
dynamax / ours, once by the wall clock and once by the process's CPU time (all threads). Other work
on the machine only adds time, so the headline figures are the smallest over all iterations
(``ratio_of_min`` = dynamax / ours); the medians are reported beside them.

Needs the bench extra: ``pip install -e ".[bench]"`` (dynamax is never a library dependency).
Usage: python experiments/bench/bench_dynamax.py [--repeats 5] [--only jdbn|cdbn]
"""
from __future__ import annotations

import argparse
import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _bench import write  # noqa: E402

K, D, NSEQ, SEQ = 41, 9, 50, 2000
SPEECH, MOTION = tuple(range(6)), (6, 7, 8)


def problem(kind: str, seed: int = 0):
    """(model (DBNModel), observations (NSEQ, SEQ, D), constraints (NSEQ, SEQ) int32)."""
    from convsynth_jax.cdbn.cdbn import sparse_structure
    from convsynth_jax.cdbn.lbg import dense_chain
    from convsynth_jax.cdbn.params import DBNModel
    from convsynth_jax.cdbn.sampler import constraint_sequence

    rng = np.random.default_rng(seed)
    x = rng.normal(size=(NSEQ, SEQ, D))
    covs = np.broadcast_to(np.eye(D), (K, D, D)).copy()
    means = rng.normal(size=(K, D))
    if kind == "jdbn":
        init, trans = dense_chain(K, 1, 0.9)
        cons = np.zeros((NSEQ, SEQ), np.int32)
        return DBNModel(means, covs, init, trans, SPEECH, MOTION, ("all",)), x, cons
    C = 3
    owners = np.zeros((K, C), bool)
    owners[0] = True                                   # shared by all constraints
    owners[K - 1, :2] = True                           # a merged state (two constraints)
    for k in range(C):
        owners[1 + 13 * k: 14 + 13 * k, k] = True
    tmask, imask = sparse_structure(owners, shared=0)
    trans = rng.uniform(0.5, 1.0, (C, K, K)) * tmask + 8.0 * np.eye(K)[None] * tmask
    trans /= trans.sum(-1, keepdims=True)
    init = imask / imask.sum(-1, keepdims=True)
    cons = np.stack([constraint_sequence(rng, SEQ, C) for _ in range(NSEQ)])
    return DBNModel(means, covs, init, trans, SPEECH, MOTION, ("other", "nod", "shake")), x, cons


def ours(model, x, cons):
    """Returns a function running one EM iteration (E-step + M-step), and the batch."""
    from convsynth_jax.cdbn.em import e_step, m_step, make_batch
    from convsynth_jax.cdbn.params import TrainParams

    batch = make_batch(list(x), list(cons), pack=True)      # as train_jdbn / train_cdbn
    tp = TrainParams()
    state = {"model": model}

    def iteration():
        st = e_step(state["model"], batch)
        state["model"] = m_step(state["model"], st, tp, warn=False)
        return st.log_likelihood

    return iteration, batch


def dynamax_fit(kind: str, model, x, cons):
    """Returns (fit(num_iters) -> log probabilities, iteration() -> log probability): dynamax's
    ``fit_em`` and one iteration of its loop body jitted once (both block until done)."""
    from functools import partial

    import jax
    import jax.numpy as jnp
    import jax.random as jr
    from dynamax.hidden_markov_model import GaussianHMM

    hmm_model = GaussianHMM(K, D)
    params, props = hmm_model.initialize(jr.PRNGKey(0), initial_probs=jnp.asarray(model.initial[0], jnp.float32),
                                         transition_matrix=jnp.asarray(model.transitions[0], jnp.float32),
                                         emission_means=jnp.asarray(model.means, jnp.float32),
                                         emission_covariances=jnp.asarray(model.covariances, jnp.float32))
    ex = jnp.asarray(x, jnp.float32)
    if kind == "jdbn":
        m, p, pr, inputs = hmm_model, params, props, None
    else:
        (m, p, pr), inputs = constrained_hmm(hmm_model, params, props, model), jnp.asarray(cons, jnp.int32)

    def fit(n):
        """``fit_em`` itself (it jits its loop anew at every call: a compile per call)."""
        _, lps = m.fit_em(p, pr, ex, inputs, num_iters=n, verbose=False)
        return jax.block_until_ready(lps)

    m_state = m.initialize_m_step_state(p, pr)

    @jax.jit
    def em_step(params):
        """The body of ``fit_em``'s loop (dynamax's code: vmapped e_step, log prior, m_step), jitted once."""
        stats, lls = jax.vmap(partial(m.e_step, params))(ex, inputs)
        lp = m.log_prior(params) + lls.sum()
        params, _ = m.m_step(params, pr, stats, m_state)
        return params, lp

    state = {"params": p}

    def iteration():
        state["params"], lp = jax.block_until_ready(em_step(state["params"]))
        return lp

    return fit, iteration


def constrained_hmm(gaussian, params, props, model):
    """A dynamax HMM with GaussianHMM's initial and emission components and constraint-indexed
    transition matrices (the inputs: (T,) int constraint codes)."""
    from typing import NamedTuple

    import jax.numpy as jnp
    from dynamax.hidden_markov_model.models.abstractions import HMM, HMMTransitions
    from dynamax.parameters import ParameterProperties

    class Params(NamedTuple):
        transition_matrices: jnp.ndarray          # (C, K, K)

    class ConstrainedTransitions(HMMTransitions):
        def distribution(self, params, state, inputs=None):
            import tensorflow_probability.substrates.jax.distributions as tfd

            return tfd.Categorical(probs=params.transition_matrices[inputs, state])

        def initialize(self, key=None, method="prior", **kw):
            raise NotImplementedError

        def log_prior(self, params):
            return 0.0

        def _compute_transition_matrices(self, params, inputs=None):
            return params.transition_matrices[inputs[1:]]                   # (T-1, K, K)

        def collect_suff_stats(self, params, posterior, inputs=None):
            C = params.transition_matrices.shape[0]
            onehot = (inputs[1:, None] == jnp.arange(C)[None, :]).astype(posterior.trans_probs.dtype)
            return jnp.einsum("tc,tij->cij", onehot, posterior.trans_probs)  # (C, K, K)

        def initialize_m_step_state(self, params, props):
            return None

        def m_step(self, params, props, batch_stats, m_step_state):
            counts = batch_stats.sum(0)
            mask = params.transition_matrices > 0
            rows = jnp.sum(counts * mask, -1, keepdims=True)
            new = jnp.where(rows > 0, jnp.where(mask, counts, 0.0) / jnp.where(rows > 0, rows, 1.0),
                            params.transition_matrices)
            return params._replace(transition_matrices=new), m_step_state

    class ConstrainedGaussianHMM(HMM):
        @property
        def inputs_shape(self):
            return ()

    cm = ConstrainedGaussianHMM(K, gaussian.initial_component, ConstrainedTransitions(), gaussian.emission_component)
    tp = Params(jnp.asarray(model.transitions, jnp.float32))
    cparams = params._replace(transitions=tp)
    cprops = props._replace(transitions=Params(ParameterProperties()))
    return cm, cparams, cprops


def bench(kind: str, repeats: int) -> dict:
    model, x, cons = problem(kind)
    ours_iter, batch = ours(model, x, cons)
    dyn, dyn_iter = dynamax_fit(kind, model, x, cons)
    t0 = time.perf_counter()
    ours_iter()
    ours_first = time.perf_counter() - t0
    t0 = time.perf_counter()
    dyn_iter()
    dyn_first = time.perf_counter() - t0
    t0 = time.perf_counter()
    dyn(2)
    fit_em_2 = time.perf_counter() - t0
    rows = []
    clocks = {"wall": time.perf_counter, "cpu": time.process_time}
    for r in range(repeats):
        row = {}
        for clock, now in clocks.items():       # each clock in its own pass (both timed alike)
            times = {"dynamax": [], "ours": []}
            for _ in range(3):                  # interleaved iteration by iteration
                for name, fn in (("dynamax", dyn_iter), ("ours", ours_iter)):
                    t0 = now()
                    fn()
                    times[name].append(now() - t0)
            row[clock] = times
        row["load_average"] = os.getloadavg()[0]
        rows.append(row)
        w, c = row["wall"], row["cpu"]
        print(f"{kind} repeat {r}: wall dynamax {np.round(w['dynamax'], 3)} ours {np.round(w['ours'], 3)}; "
              f"cpu dynamax {np.round(c['dynamax'], 3)} ours {np.round(c['ours'], 3)}; "
              f"load {row['load_average']:.2f}", flush=True)
    out = {"states": K, "dims": D, "sequences": NSEQ, "frames": NSEQ * SEQ,
           "constraints": int(model.num_constraints), "structural_zeros": int((model.transitions == 0).sum()),
           "batch_shape": list(batch.x.shape), "ours_first_call_seconds": ours_first,
           "dynamax_first_call_seconds": dyn_first, "dynamax_fit_em_2_iterations_seconds": fit_em_2,
           "repeats": rows}
    for clock in clocks:
        d = [t for r in rows for t in r[clock]["dynamax"]]
        o = [t for r in rows for t in r[clock]["ours"]]
        # load only adds time: the smallest figure is the least disturbed one
        out[clock] = {"dynamax_iteration_seconds_min": min(d), "ours_iteration_seconds_min": min(o),
                      "ratio_of_min": min(d) / min(o), "dynamax_iteration_seconds_median": float(np.median(d)),
                      "ours_iteration_seconds_median": float(np.median(o)),
                      "ratio_of_median": float(np.median(d) / np.median(o))}
    print(kind, {k: out[k] for k in clocks}, flush=True)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--only", choices=("jdbn", "cdbn"), default=None)
    ap.add_argument("--name", default="bench_dynamax")
    args = ap.parse_args()
    warnings.simplefilter("ignore", RuntimeWarning)
    import dynamax
    import jax

    res = {"machine": {"cpus": os.cpu_count(), "load_average_at_start": os.getloadavg()},
           "versions": {"jax": jax.__version__, "dynamax": getattr(dynamax, "__version__", "?")}}
    for kind in ("jdbn", "cdbn"):
        if args.only in (None, kind):
            res[kind] = bench(kind, args.repeats)
    res["machine"]["load_average_at_end"] = os.getloadavg()
    write(args.name, res, overrides=[f"--repeats={args.repeats}"] + ([f"--only={args.only}"] if args.only else []))


if __name__ == "__main__":
    main()
