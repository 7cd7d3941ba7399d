"""Benchmark: the full leave-one-out sweep on the synthetic default corpus (17 folds x 4 conditions,
both characters) in one process, as the basic Hydra launcher runs it. Goal: under 15 minutes on the
2-core machine. Writes ``bench_loo.json`` under experiments/results/ and the collected tables to
experiments/results/loo_default/.

    python experiments/bench/bench_loo.py [--folds N] [--cache DIR]
"""
import argparse
import json
import os
import time
from pathlib import Path

import pandas as pd

from convsynth_jax.manifest import run_manifest

from convsynth_jax.config import default_params
from convsynth_jax.evaluation.collect import write_collected
from convsynth_jax.evaluation.loo import recording_threshold_table, run_fold
from convsynth_jax.systems.base import make_system
from convsynth_jax.api import annotated_corpus, cache_dir, REPO

if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--folds", type=int, default=None)
    ap.add_argument("--cache", default=str(REPO / "data_cache"))
    ap.add_argument("--out", default=str(REPO / "experiments" / "results" / "loo_default"))
    ap.add_argument("--partial", default=None, help="CSV rewritten after every fold with the cases so far")
    ap.add_argument("overrides", nargs="*", help="config overrides, e.g. system=random_playback")
    args = ap.parse_args()
    t0 = time.perf_counter()
    manifest = run_manifest(overrides=args.overrides)  # taken at the start: the commit that ran
    params = default_params([f"cache_dir={args.cache}", "progress=false", *args.overrides])
    system = make_system(params, params.system)
    corpus, ann = annotated_corpus(params)
    t_corpus, t_ann = 0.0, time.perf_counter() - t0
    cache = cache_dir(params)
    frames = []
    thresholds = recording_threshold_table(ann, params.annotate)
    n = args.folds or len(corpus.sessions)
    for fold in range(n):
        models: dict = {}
        for cond in system.conditions:
            tf = time.perf_counter()
            frames.append(run_fold(system, ann, fold, cond, params, cache_dir=cache, models=models,
                                   with_audio=system.needs_audio, thresholds=thresholds))
            print(f"fold {fold} {cond}: {time.perf_counter() - tf:.1f} s", flush=True)
        if args.partial:  # the cases so far, kept if the run is cut short
            Path(args.partial).parent.mkdir(parents=True, exist_ok=True)
            pd.concat(frames, ignore_index=True).to_csv(args.partial, index=False)
    cases = pd.concat(frames, ignore_index=True)
    out = Path(args.out)
    write_collected(cases, out)
    total = time.perf_counter() - t0
    rates = pd.read_csv(out / "success_rates.csv")
    result = {"system": system.name, "folds": n, "conditions": len(system.conditions), "windows_per_condition": int(rates["windows"].iloc[0]),
              "total_seconds": total, "corpus_and_annotation_seconds": t_ann,
              "success_rates": rates.to_dict(orient="records"), "goal_seconds": 900}
    (out / "bench_loo.json").write_text(json.dumps(result, indent=2))
    manifest["load_avg_1_5_15_at_end"] = list(os.getloadavg())
    (out / "manifest.json").write_text(json.dumps(manifest, indent=2) + "\n")
    print(json.dumps(result, indent=2))
