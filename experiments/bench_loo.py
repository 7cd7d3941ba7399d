"""Benchmark: the full leave-one-out sweep on the synthetic default corpus (17 folds x 4 conditions,
both characters) in one process, as the basic Hydra launcher runs it. Goal: under 15 minutes on the
2-core machine. Writes experiments/results/bench_loo.json and the collected tables to
experiments/results/loo_default/.

    python experiments/bench_loo.py [--folds N] [--cache DIR]
"""
import argparse
import json
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

import pandas as pd  # noqa: E402

from convsynth_jax.config import compose  # noqa: E402
from convsynth_jax.evaluation.collect import write_collected  # noqa: E402
from convsynth_jax.evaluation.loo import annotate_corpus_cached, run_fold  # noqa: E402
from convsynth_jax.tasks.common import open_corpus  # noqa: E402

if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--folds", type=int, default=None)
    ap.add_argument("--cache", default=str(REPO / "data_cache"))
    args = ap.parse_args()
    t0 = time.perf_counter()
    cfg = compose([f"cache_dir={args.cache}", "progress=false"])
    corpus = open_corpus(cfg)
    t_corpus = time.perf_counter() - t0
    cache = Path(args.cache) / "loo_cache"
    ann = annotate_corpus_cached(corpus, cfg, cache)
    t_ann = time.perf_counter() - t0 - t_corpus
    frames = []
    n = args.folds or len(corpus.sessions)
    for fold in range(n):
        for cond in ("all", "no_lr", "no_hp", "none"):
            tf = time.perf_counter()
            frames.append(run_fold(corpus, ann, fold, cond, cfg, cache_dir=cache))
            print(f"fold {fold} {cond}: {time.perf_counter() - tf:.1f} s", flush=True)
    cases = pd.concat(frames, ignore_index=True)
    out = REPO / "experiments" / "results" / "loo_default"
    write_collected(cases, out)
    total = time.perf_counter() - t0
    rates = pd.read_csv(out / "success_rates.csv")
    result = {"folds": n, "conditions": 4, "test_cases_per_condition": int(rates["cases"].iloc[0]),
              "total_seconds": total, "corpus_seconds": t_corpus, "annotation_seconds": t_ann,
              "success_rates": rates.to_dict(orient="records"), "goal_seconds": 900}
    (REPO / "experiments" / "results" / "bench_loo.json").write_text(json.dumps(result, indent=2))
    print(json.dumps(result, indent=2))
