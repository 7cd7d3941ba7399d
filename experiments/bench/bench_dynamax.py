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

Timing: dynamax's EM is one jitted ``lax.scan`` over iterations; an iteration is
(time of 5 iterations - time of 2 iterations) / 3, both compiled before timing (compile excluded).
Ours is ``e_step`` + ``m_step`` (the E-step jitted, the M-step float64 NumPy on the host, as
``fit_em`` runs it), compiled before timing. Each repeat times dynamax(5), dynamax(2) and three of
our iterations back to back, once by the wall clock and once by the process's CPU time (all
threads; less sensitive to other work on a shared machine); the ratio is dynamax / ours per repeat,
reported as the median (and the smallest by wall clock).

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
    """Returns fit(num_iters) -> log probabilities (blocks until done)."""
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
        def fit(n):
            _, lps = hmm_model.fit_em(params, props, ex, num_iters=n, verbose=False)
            return jax.block_until_ready(lps)
        return fit
    cmodel, cparams, cprops = constrained_hmm(hmm_model, params, props, model)
    inputs = jnp.asarray(cons, jnp.int32)

    def fit(n):
        _, lps = cmodel.fit_em(cparams, cprops, ex, inputs, num_iters=n, verbose=False)
        return jax.block_until_ready(lps)
    return fit


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
    dyn = dynamax_fit(kind, model, x, cons)
    t0 = time.perf_counter()
    ours_iter()
    ours_first = time.perf_counter() - t0
    t0 = time.perf_counter()
    dyn(2)
    dyn(5)
    dyn_first = time.perf_counter() - t0
    rows = []
    clocks = {"wall": time.perf_counter, "cpu": time.process_time}
    for r in range(repeats):
        row = {}
        for clock, now in clocks.items():       # each clock in its own pass (both timed alike)
            t0 = now()
            dyn(5)
            t5 = now() - t0
            t0 = now()
            dyn(2)
            t2 = now() - t0
            t0 = now()
            for _ in range(3):
                ours_iter()
            t_ours = (now() - t0) / 3
            d = (t5 - t2) / 3
            row.update({f"dynamax_iteration_{clock}_seconds": d, f"ours_iteration_{clock}_seconds": t_ours,
                        f"ratio_{clock}": d / t_ours})
        row["load_average"] = os.getloadavg()[0]
        rows.append(row)
        print(f"{kind} repeat {r}: wall dynamax {row['dynamax_iteration_wall_seconds']:.3f} s, ours "
              f"{row['ours_iteration_wall_seconds']:.3f} s, ratio {row['ratio_wall']:.2f}; cpu dynamax "
              f"{row['dynamax_iteration_cpu_seconds']:.3f} s, ours {row['ours_iteration_cpu_seconds']:.3f} s, "
              f"ratio {row['ratio_cpu']:.2f}; load {row['load_average']:.2f}", flush=True)
    med = lambda key: float(np.median([r[key] for r in rows]))
    return {"states": K, "dims": D, "sequences": NSEQ, "frames": NSEQ * SEQ,
            "constraints": int(model.num_constraints),
            "structural_zeros": int((model.transitions == 0).sum()),
            "batch_shape": list(batch.x.shape),
            "ours_first_call_seconds": ours_first, "dynamax_compile_and_first_calls_seconds": dyn_first,
            **{f"{k}_median": med(k) for k in rows[0] if k != "load_average"},
            "ratio_wall_min": float(np.min([r["ratio_wall"] for r in rows])), "repeats": rows}


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
