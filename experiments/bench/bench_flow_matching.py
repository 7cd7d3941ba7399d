"""The flow-matching system's leave-one-out sweep, timed: training per fold and character, sampling
speed (seconds per 60 s of speech), the whole sweep (training, sampling and leave-one-out's own
metrics, as ``task=loo`` runs them), wall and CPU, on this machine.

    nice -n 10 python experiments/bench/bench_flow_matching.py [--folds 0 1 ...] [--override KEY=VALUE ...]
        [--cache DIR]   # default: a fresh folder, so every fold trains

Writes bench_flow_matching.json (and its manifest) into experiments/results/; BVH of every window and each
fold's cases.csv go to --out (default /tmp/flow_matching_sweep/flow_matching/<fold>), in the layout ``task=benchmark
task.from_dir`` reads (``<out>/<fold>/cases.csv``, ``bvh/``).
"""
import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np  # noqa: E402

from convsynth_jax.evaluation.loo import recording_threshold_table, run_fold  # noqa: E402
from convsynth_jax.utils import atomic_path  # noqa: E402
from convsynth_jax.api import loo_setup, write_result as write  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--folds", type=int, nargs="+", default=None, help="default: every fold")
    ap.add_argument("--override", nargs="*", default=[])
    ap.add_argument("--cache", default=None, help="model cache (default: a fresh folder: every fold trains)")
    ap.add_argument("--out", default="/tmp/flow_matching_sweep/flow_matching")
    ap.add_argument("--name", default="bench_flow_matching")
    args = ap.parse_args()
    t_start, cpu_start = time.perf_counter(), time.process_time()
    params, ann, system = loo_setup(["system=flow_matching", *args.override])
    folds = args.folds if args.folds is not None else list(range(len(ann)))
    cache = Path(args.cache) if args.cache else Path(tempfile.mkdtemp(prefix="flow_bench_cache_"))
    table = recording_threshold_table(ann, params.annotate)
    setup_s = time.perf_counter() - t_start
    per_fold = []
    for fold in folds:
        t0, c0 = time.perf_counter(), time.process_time()
        job = Path(args.out) / str(fold)
        job.mkdir(parents=True, exist_ok=True)
        df = run_fold(system, ann, fold, "audio", params, out_dir=job, cache_dir=cache, export_bvh=True,
                      with_audio=True, thresholds=table)
        df["job_dir"] = "."
        with atomic_path(job / "cases.csv") as tmp:
            df.to_csv(tmp, index=False)
        fit = df.groupby("character")["fit_seconds"].first().to_dict()
        speech = float((df["window_end"] - df["window_start"]).sum())
        synth = float(df["synthesis_seconds"].sum())
        row = {"fold": fold, "seconds": time.perf_counter() - t0, "cpu_seconds": time.process_time() - c0,
               "fit_seconds": fit, "synthesis_seconds": synth, "speech_seconds": speech,
               "windows": int(len(df)), "success": int(df["success"].sum()),
               "load_1min": os.getloadavg()[0]}
        per_fold.append(row)
        print(f"fold {fold}: {row['seconds']:.1f} s (cpu {row['cpu_seconds']:.1f} s), fit "
              f"{', '.join(f'{k} {v:.1f} s' for k, v in fit.items())}, sampling {synth:.1f} s for {speech:.0f} s of "
              f"speech, {row['success']}/{row['windows']} windows, load {row['load_1min']:.1f}", flush=True)
    total = time.perf_counter() - t_start
    fits = [v for r in per_fold for v in r["fit_seconds"].values()]
    speech = sum(r["speech_seconds"] for r in per_fold)
    result = {"folds": folds, "overrides": args.override, "options": dict(params.system.options),
              "sweep_seconds": total, "sweep_cpu_seconds": time.process_time() - cpu_start, "setup_seconds": setup_s,
              "sweep_minutes": total / 60.0, "goal_minutes_17_folds": 45.0,
              "fit_seconds_per_character": {"mean": float(np.mean(fits)), "max": float(np.max(fits))},
              "sampling_seconds_per_60s_speech": sum(r["synthesis_seconds"] for r in per_fold) / speech * 60.0,
              "windows": sum(r["windows"] for r in per_fold), "success": sum(r["success"] for r in per_fold),
              "per_fold": per_fold, "cpu_count": os.cpu_count(), "out": args.out}
    write(args.name, result, overrides=[f"folds={folds}", *args.override])


if __name__ == "__main__":
    main()
