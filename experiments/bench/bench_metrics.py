"""Benchmark of the field-standard metrics: metric time for all windows x systems once
synthesis is done (goal <= 60 s), autoencoder training time (goal <= 3 min on the 2-core CPU), and
the validity figures (FGD of ground truth with noise and block shuffling, odd/even noise floor, beat
consistency with own vs other audio).

    python experiments/bench/bench_metrics.py SWEEPS [overrides...]

SWEEPS: a folder with one finished ``task=loo task.export_bvh=true`` sweep per system label (as
``task.from_dir``). Writes experiments/results/bench_metrics.json + manifest.
"""
import sys
import time

import numpy as np

from convsynth_jax.config import compose, task_settings
from convsynth_jax.evaluation import benchmark as bm
from convsynth_jax.evaluation.field import fgd
from convsynth_jax.evaluation.field.autoencoder import encode
from convsynth_jax.evaluation.field.views import motion_view
from convsynth_jax.api import RESULTS, annotated_corpus, autoencoder_training, params_of, timed, write_result


def main(argv):
    src, overrides = argv[0], ["task=benchmark", "progress=false", *argv[1:]]
    cfg = compose(overrides)
    params, task = params_of(cfg), task_settings(cfg)
    mp = task.metrics
    _, ann = annotated_corpus(params)
    fps, loo = params.fps, params.loo
    cases = bm.benchmark_cases(ann, fps, loo.window, loo.hop, loo.max_windows, task.folds)
    gt, mm = bm.controls(ann, cases, fps, loo.window, loo.hop)
    systems = [gt, mm]
    for label, e in task.systems.items():
        scopes = ("head",) if e.system == "cdbn" else ("body", "head")
        systems.append(bm.sweep_motions(f"{src}/{label}", label, e.condition, cases, scopes))
    training, ae_source = autoencoder_training(params, task)
    aes, ae_s = timed(bm.train_autoencoders, training, mp, params.annotate, ("body", "head"), None)  # no cache: trained
    audio, audio_read_s = timed(lambda: {c.key: bm.case_audio(ann, c, fps) for c in cases})
    res, metrics_s = timed(bm.score_benchmark, cases, systems, audio, fps, mp, params.annotate, aes)
    # validity on the ground truth (body scope)
    views = [motion_view(gt.motions[c.key][2], "body", mp.joints, params.annotate).relative for c in cases]
    rng = np.random.default_rng(mp.seed)

    def feats(rels):
        raw = np.concatenate([fgd.raw_window_features(r, mp.fgd.raw_window_frames, mp.fgd.raw_frame_step) for r in rels])
        ae = {w: np.concatenate([encode(m, r) for r in rels]) for (s, w), m in aes.items() if s == "body"}
        return {"raw": raw, **{f"ae{w}": v for w, v in ae.items()}}

    def shuffle(r, block):
        n = len(r) // block
        return np.concatenate([r[k * block:(k + 1) * block] for k in rng.permutation(n)] + [r[n * block:]])

    ref = feats(views)
    validity = {"noise": {}, "shuffle_1s": {}, "odd_even_floor": {}}
    for s in mp.noise_levels:
        f = feats([r + rng.normal(0, s, r.shape) for r in views])
        validity["noise"][str(s)] = {k: fgd.fgd(ref[k], f[k], mp.fgd.eps) for k in ref}
    f = feats([shuffle(r, int(mp.shuffle_block * fps)) for r in views])
    validity["shuffle_1s"] = {k: fgd.fgd(ref[k], f[k], mp.fgd.eps) for k in ref}
    # noise floor: odd against even windows (both characters in each half)
    fo = feats([v for v, c in zip(views, cases) if c.window % 2])
    fe = feats([v for v, c in zip(views, cases) if not c.window % 2])
    validity["odd_even_floor"] = {k: fgd.fgd(fo[k], fe[k], mp.fgd.eps) for k in ref}
    bc = res.rows[res.rows["scope"] == "body"].groupby("system")["beat_consistency"].mean()
    validity["bc_own_vs_other"] = {"own": float(bc.get(bm.GROUND_TRUTH, np.nan)),
                                   "other_session": float(bc.get(bm.MISMATCHED, np.nan))}
    ok = res.rows[res.rows["status"] == "ok"]
    out = {
        "windows": len(cases), "scored_rows": int(len(ok)), "rows": int(len(res.rows)),
        "systems": [s.name for s in systems], "metrics_seconds": metrics_s, "metrics_breakdown_s": res.seconds,
        "metrics_goal_s": 60.0, "audio_read_seconds": audio_read_s,
        "autoencoder_training_seconds": ae_s,
        "autoencoder_each_s": {f"{k[0]}_w{k[1]}": v.seconds for k, v in aes.items()},
        "autoencoder_final_loss": {f"{k[0]}_w{k[1]}": v.loss for k, v in aes.items()},
        "autoencoder_goal_s": 180.0, "autoencoder_training_data": ae_source, "validity": validity,
        "bc_note": "beat_consistency, body scope, mean over windows",
    }

    RESULTS.mkdir(parents=True, exist_ok=True)
    res.leaderboard.to_csv(RESULTS / "bench_metrics_leaderboard.csv", index=False)
    (RESULTS / "bench_metrics_leaderboard.md").write_text(bm.leaderboard_markdown(res.leaderboard))
    write_result("bench_metrics", out, overrides=overrides)


if __name__ == "__main__":
    t0 = time.perf_counter()
    main(sys.argv[1:])
    print(f"total {time.perf_counter() - t0:.1f} s")
