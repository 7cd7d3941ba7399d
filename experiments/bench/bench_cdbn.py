"""CDBN benchmark and acceptance figures (prints them; writes experiments/results/bench_cdbn.json).

1. one EM iteration (E-step on the JAX smoother + float64 M-step) on 100k frames, 41 states, 9-D;
2. 1 minute of speech -> head motion (Praat prosody, posteriors, key-point smoothing), warm;
3. planted recovery: ~60k frames from a planted CDBN (3 constraints, N = 4, one state shared by two
   constraints, one shared by all): held-out log-likelihood vs the true model's, states recovered
   within 0.25 SD, transition L-inf error, structural zeros;
4. optionally (--eval) the whole ``convsynth task=cdbn_eval`` wall time;
5. optionally (--hands) the hand model (Table V analogue: jDBN vs CDBN on the 10-D arm/forearm
   stream) on the synthetic dyadic corpus (audio-label constraints) and on real Bandai2 raise/wave
   mocap (gesture constraints, paired with real speech that is unrelated to the motion), written to
   experiments/results/bench_cdbn_hands.json.
The Fig. 6 random-initialization study (--fig6) and the Eq. 8 convergence check (--distance) were
retired with their findings in docs/cdbn.md and docs/results.md; the script at commit e1848f1 has them,
experiments/results/bench_cdbn_fig6.json keeps the study's figures.
No assertions: the figures are for the README and the report. Usage:
    python experiments/bench/bench_cdbn.py [--eval] [--hands --cache DIR] [--out NAME]
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import time
import warnings
from pathlib import Path

import numpy as np

from convsynth_jax.api import REPO, SHARED_DATA, write_result


def bench_em(K=41, frames=100_000, seq=2000):
    from convsynth_jax.cdbn.em import e_step, m_step, make_batch
    from convsynth_jax.cdbn.lbg import dense_chain
    from convsynth_jax.cdbn.params import DBNModel, TrainParams

    rng = np.random.default_rng(0)
    x = rng.normal(size=(frames, 9))
    seqs = np.split(x, frames // seq)
    cons = [rng.integers(0, 3, len(s)) for s in seqs]
    init, trans = dense_chain(K, 3, 0.9)
    covs = np.broadcast_to(np.eye(9), (K, 9, 9)).copy()
    model = DBNModel(rng.normal(size=(K, 9)), covs, init, trans, tuple(range(6)), (6, 7, 8), ("a", "b", "c"))
    b = make_batch(seqs, cons)
    t0 = time.perf_counter()
    st = e_step(model, b)
    first = time.perf_counter() - t0
    times = []
    for _ in range(3):
        t0 = time.perf_counter()
        st = e_step(model, b)
        model = m_step(model, st, TrainParams(), warn=False)
        times.append(time.perf_counter() - t0)
    return {"frames": frames, "states": K, "dims": 9, "sequences": len(seqs), "first_call_seconds": first,
            "em_iteration_seconds": float(np.median(times)), "em_iteration_seconds_all": times}


def bench_synthesis():
    from convsynth_jax.cdbn.features import Normalization, speech_features
    from convsynth_jax.cdbn.lbg import dense_chain
    from convsynth_jax.cdbn.params import DBNModel, CDBNFeatureParams
    from convsynth_jax.cdbn.synthesize import keypoint_smooth, synthesize_head
    from convsynth_jax.io.audio import Audio, load_audio

    src = SHARED_DATA / "speech" / "acoustic_corpus.wav"
    if src.is_file():
        a = load_audio(src)
        x = np.asarray(a.samples, np.float32)
        reps = int(np.ceil(60.0 * a.sample_rate / len(x)))
        audio = Audio(np.tile(x, reps)[: int(60 * a.sample_rate)], a.sample_rate, str(src))
        what = f"{src.name} tiled to 60 s"
    else:
        from convsynth_jax.data.synthetic import Segment, _render_voice

        rng = np.random.default_rng(0)
        words = [(t, t + 0.3, "w", False) for t in np.arange(0.2, 59.5, 0.4)]
        sig, _ = _render_voice([Segment("a", "PC", 0.2, 59.5, 1.0, words)], 150.0, 60.0, 16000, rng, 0.28)
        audio, what = Audio(sig.astype(np.float32), 16000, "synthetic"), "synthetic voice, 60 s"
    K = 22
    rng = np.random.default_rng(1)
    init, trans = dense_chain(K, 3, 0.9)
    model = DBNModel(rng.normal(size=(K, 9)), np.broadcast_to(np.eye(9), (K, 9, 9)).copy(), init, trans,
                     tuple(range(6)), (6, 7, 8), ("other", "nod", "shake"))
    cons = np.repeat(rng.integers(0, 3, 60), 30)
    fp = CDBNFeatureParams()
    out = {}
    for run in ("cold", "warm", "warm2"):
        t0 = time.perf_counter()
        raw = speech_features(audio, fp, 1800, 30.0)
        t1 = time.perf_counter()
        ang, _ = synthesize_head(model, Normalization.fit(raw).apply(raw), cons, "smoother", np.zeros(3), np.ones(3))
        keypoint_smooth(ang, 30.0, 15.0)
        t2 = time.perf_counter()
        out[run] = {"features_seconds": t1 - t0, "inference_and_smoothing_seconds": t2 - t1, "total_seconds": t2 - t0}
    return {"audio": what, "frames": 1800, "states": K, **out}


def bench_planted(nseq=60, length=1000):
    from convsynth_jax.cdbn.cdbn import train_cdbn
    from convsynth_jax.cdbn.em import e_step, make_batch
    from convsynth_jax.cdbn.params import TrainParams
    from convsynth_jax.cdbn.sampler import planted_cdbn, recovery_report, sample

    rng = np.random.default_rng(0)
    true, _ = planted_cdbn(rng)
    tr = sample(true, rng, nseq, length)
    te = sample(true, np.random.default_rng(99), 10, length)
    t0 = time.perf_counter()
    tm = train_cdbn(tr.observations, tr.constraints, 4, true.speech_dims, true.motion_dims,
                    TrainParams(max_iter=50, tol=1e-5), true.constraint_names)
    secs = time.perf_counter() - t0
    rep = recovery_report(true, tm.model)
    b = make_batch(te.observations, te.constraints)
    ll_t = e_step(true, b).log_likelihood / b.num_frames
    ll_e = e_step(tm.model, b).log_likelihood / b.num_frames
    perm = np.asarray(rep["perm"])
    same_structure = bool(np.array_equal(tm.model.transitions[:, perm][:, :, perm] > 0, true.transitions > 0)) \
        if tm.model.num_states == true.num_states else False
    return {"train_frames": nseq * length, "heldout_frames": b.num_frames, "train_seconds": secs,
            "em_iterations": len(tm.log_likelihoods), "heldout_loglik_true": ll_t, "heldout_loglik_estimated": ll_e,
            "loglik_relative_gap": abs(ll_e - ll_t) / abs(ll_t), "states_true": true.num_states,
            "states_estimated": tm.model.num_states, "states_recovered_fraction": rep["states_recovered"],
            "transition_linf": rep["transition_linf"], "transition_linf_per_constraint": rep["transition_linf_per_constraint"],
            "structural_zeros": int((tm.model.transitions == 0).sum()), "same_sparsity_as_planted": same_structure,
            "merges": [list(m) for m in tm.merges]}


def bench_eval():
    import tempfile

    from convsynth_jax.config import compose, run_task

    out = Path(tempfile.mkdtemp(prefix="bench_cdbn_eval_"))
    t0 = time.perf_counter()
    s = run_task(compose(["task=cdbn_eval", f"cache_dir={out / 'cache'}"]), out)
    return {"wall_seconds": time.perf_counter() - t0, "out_dir": str(out), "table": s["table"],
            "gesture_accuracy": s["gesture_accuracy"], "transition_distance": s["transition_distance"],
            "init_comparison": s["init_comparison"], "phase_seconds": s["phase_seconds"]}


def _hand_table(turns, rig, names, ep_kw):
    from convsynth_jax.cdbn.hand_eval import hand_evaluation

    return hand_evaluation(turns, rig, names, ep_kw)


def bench_hands(cache: str, dyadic_sessions: int = 6, bandai_clips: int | None = None):
    from convsynth_jax.cdbn.hand_eval import (
        BANDAI_CONSTRAINTS,
        DYADIC_CONSTRAINTS,
        bandai_hand_turns,
        dyadic_hand_turns,
    )
    from convsynth_jax.cdbn.params import CDBNFeatureParams
    from convsynth_jax.config import default_params
    from convsynth_jax.api import annotated_corpus

    out = {}
    ep = {"folds": 10, "jdbn_grid": (8, 12), "cdbn_grid": (3, 4), "max_test_folds": 3}
    fp = CDBNFeatureParams()
    bandai = SHARED_DATA / "bandai2" / "bvh"
    wav = SHARED_DATA / "speech" / "acoustic_corpus.wav"
    if bandai.is_dir() and wav.is_file():
        turns, rig = bandai_hand_turns(bandai, wav, fp, max_clips=bandai_clips)
        out["bandai2"] = {"speech": f"{wav.name} excerpts (unrelated to the motion)",
                          **_hand_table(turns, rig, BANDAI_CONSTRAINTS, ep)}
        print("bandai2 hands:", json.dumps(out["bandai2"]["table"], default=float), out["bandai2"]["gesture_accuracy"],
              flush=True)
    params = default_params([f"cache_dir={cache}", "progress=false"])
    corpus, ann = annotated_corpus(params)
    turns, rig = dyadic_hand_turns(corpus, ann, fp, max_sessions=dyadic_sessions)
    out["dyadic"] = {"sessions": dyadic_sessions, **_hand_table(turns, rig, DYADIC_CONSTRAINTS, ep)}
    print("dyadic hands:", json.dumps(out["dyadic"]["table"], default=float), flush=True)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--eval", action="store_true", help="also time the whole task=cdbn_eval")
    ap.add_argument("--out", default="bench_cdbn", help="result name under experiments/results/")
    ap.add_argument("--hands", action="store_true", help="only the hand-model evaluation (bench_cdbn_hands.json)")
    ap.add_argument("--cache", default=str(REPO / "data_cache"), help="cache_dir of the dyadic corpus (--hands)")
    ap.add_argument("--dyadic-sessions", type=int, default=6)
    ap.add_argument("--bandai-clips", type=int, default=None)
    args = ap.parse_args()
    if args.hands:
        warnings.simplefilter("ignore", RuntimeWarning)
        t0 = time.perf_counter()
        res = {"load_average_at_start": os.getloadavg(), **bench_hands(args.cache, args.dyadic_sessions, args.bandai_clips)}
        res["load_average_at_end"], res["wall_seconds"] = os.getloadavg(), time.perf_counter() - t0
        write_result("bench_cdbn_hands" if args.out == "bench_cdbn" else args.out, res)
        return
    warnings.simplefilter("ignore", RuntimeWarning)
    res = {"machine": {"python": platform.python_version(), "cpus": os.cpu_count(),
                       "load_average_at_start": os.getloadavg()}}
    for name, fn in (("em_iteration", bench_em), ("synthesis_1min", bench_synthesis), ("planted_recovery", bench_planted)):
        t0 = time.perf_counter()
        res[name] = fn()
        print(f"{name} ({time.perf_counter() - t0:.1f} s): {json.dumps(res[name], default=float)}", flush=True)
    if args.eval:
        res["cdbn_eval"] = bench_eval()
        print(f"cdbn_eval: {res['cdbn_eval']['wall_seconds']:.1f} s")
    res["machine"]["load_average_at_end"] = os.getloadavg()
    write_result(args.out, res)


if __name__ == "__main__":
    main()
