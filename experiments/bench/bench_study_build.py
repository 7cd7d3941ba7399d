"""Benchmark of ``task=study_build`` for the paper's 4 pairs x 5 segments on the default corpus
(goal: <= 5 min on the 2-core machine; docs/study.md).

    python experiments/bench/bench_study_build.py [--segments 5] [--prepared DIR]

Step 1 (not timed against the goal, reported): the default synthetic corpus and its annotation in a
prepared cache folder (``--prepared``, default ``data_cache``; reused when present), as every task
on that corpus shares them. Step 2 (the goal): ``convsynth task=study_build task.segments=5`` in a
fresh process with a fresh cache folder that holds only the annotation (graphs fitted, kernels
compiled, windows synthesized, videos rendered: everything the task does). Writes
experiments/results/bench_study_build.json (+ manifest): wall and CPU seconds, the task's own
synthesis and render times, the stimuli, the load average before and after."""
import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from convsynth_jax.api import REPO, write_result



def _cpu_children() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--segments", type=int, default=5)
    ap.add_argument("--prepared", default=str(REPO / "data_cache"))
    args = ap.parse_args()
    prepared = Path(args.prepared).resolve()
    exe = [sys.executable, "-m", "convsynth_jax.config"]
    env = {**os.environ, "CONVSYNTH_CACHE": str(prepared)}
    t0, c0 = time.perf_counter(), _cpu_children()
    prepare = ("from convsynth_jax.config import default_params; from convsynth_jax.api import annotated_corpus; "
               "annotated_corpus(default_params(['progress=false']))")
    subprocess.run([sys.executable, "-c", prepare], check=True, env=env, cwd=REPO)
    prep = {"wall_s": time.perf_counter() - t0, "cpu_s": _cpu_children() - c0}
    corpus = prepared / "synthetic_default"
    with tempfile.TemporaryDirectory() as tmp:
        cache = Path(tmp) / "cache"
        (cache / "loo_cache").mkdir(parents=True)
        for f in (prepared / "loo_cache").glob("annotations_*.pkl"):
            shutil.copy2(f, cache / "loo_cache" / f.name)
        out = Path(tmp) / "run"
        load_before = os.getloadavg()
        t0, c0 = time.perf_counter(), _cpu_children()
        overrides = [f"task.segments={args.segments}", f"corpus.root={corpus}", f"cache_dir={cache}", "progress=false",
                     f"hydra.run.dir={out}"]
        subprocess.run([*exe, "task=study_build", *overrides], check=True, env={**os.environ}, cwd=REPO)
        wall, cpu = time.perf_counter() - t0, _cpu_children() - c0
        load_after = os.getloadavg()
        summary = json.loads((out / "summary.json").read_text())
        manifest = json.loads((out / "study" / "manifest.json").read_text())
        sizes = sum(s["bytes"] for s in manifest["stimuli"])
    result = {"segments": args.segments, "pairs": len(manifest["study"]["pairs"]), "stimuli": summary["num_stimuli"],
              "attention_stimuli": summary["num_attention"], "rejected_windows": summary["rejected_windows"],
              "wall_s": wall, "cpu_s": cpu, "goal_s": 300.0, "met": wall <= 300.0, "task_timings": summary["timings"],
              "video_bytes": sizes, "prepare_corpus_and_annotation": prep,
              "loadavg_before": list(load_before), "loadavg_after": list(load_after), "cpu_count": os.cpu_count()}
    write_result("bench_study_build", result, overrides=["task=study_build", *overrides[:1]])


if __name__ == "__main__":
    main()
