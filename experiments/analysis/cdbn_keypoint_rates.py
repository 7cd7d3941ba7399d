"""The key-point rate ``cdbn.synth.match_jerk`` (ours, preset=quality) picks per character, fold and
condition on leave-one-out folds of the configured corpus (default: the default synthetic corpus).

    python experiments/analysis/cdbn_keypoint_rates.py [--folds 0 1 2] [--override ...]

Writes experiments/results/cdbn_keypoint_rates.json (with a manifest).
"""
import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))

from _bench import loo_setup, write  # noqa: E402

from convsynth_jax.evaluation.loo import fit_fold  # noqa: E402
from convsynth_jax.api import cache_dir  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--folds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--override", nargs="*", default=[])
    args = ap.parse_args()
    t0 = time.perf_counter()
    over = ["system=cdbn", "preset=quality", *args.override]
    params, ann, system = loo_setup(over)
    names = list(ann)
    rates = {}
    for fold in args.folds:
        for cond in ("cdbn", "jdbn"):
            fitted = fit_fold(system, ann, names[fold], cond, cache_dir(params))
            rates[f"fold{fold}_{cond}"] = {c: m.keypoints_per_second for c, m in fitted.items()}
            print(fold, cond, rates[f"fold{fold}_{cond}"], flush=True)
    write("cdbn_keypoint_rates", {"folds": args.folds, "overrides": over, "paper_rate": system.cdbn.synth.keypoints_per_second,
                                  "rates": rates, "seconds": time.perf_counter() - t0}, overrides=over)


if __name__ == "__main__":
    main()
