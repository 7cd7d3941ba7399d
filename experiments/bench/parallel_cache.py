"""Reliability check: several ``convsynth`` processes started together on one empty cache (docs/reliability.md).

Two scenarios, each on a fresh, empty ``CONVSYNTH_CACHE``:
  1. ``--processes N`` (default 4) ``convsynth task=cooccurrence corpus=synthetic_tiny`` started at once;
  2. one joblib multirun of 4 jobs (``-m hydra/launcher=joblib hydra.launcher.n_jobs=4``) over
     ``stats.n_permutations``, so the jobs share the corpus and the annotation.
Reported per scenario: how many processes or jobs succeeded, whether their ``cooccurrence.csv`` are
identical (scenario 1; in scenario 2 the ``matched``/``total`` columns, which do not depend on the
swept value), how many times the corpus was generated (log lines "generating synthetic corpus"), and
whether every cache file reads back (annotation pickles, motion graphs, stored kernels, JAX entries).
The test tests/test_shared_cache.py covers the same race with 4 small processes; this script runs
the full command line, too slow for CI.

    python experiments/bench/parallel_cache.py [--processes N]
"""
import argparse
import hashlib
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from convsynth_jax.api import REPO, write_result
from convsynth_jax.testing.cache_race import cache_report


BASE = ["task=cooccurrence", "corpus=synthetic_tiny", "progress=false"]


def _env(cache: Path) -> dict:
    return dict(os.environ, CONVSYNTH_CACHE=str(cache), PYTHONPATH=str(REPO), CONVSYNTH_WORKERS="1")


def _convsynth(args):
    return [sys.executable, "-m", "convsynth_jax.config", *args]


def _digest(path: Path) -> str | None:
    return hashlib.sha256(path.read_bytes()).hexdigest() if path.is_file() else None


def together(n: int, work: Path) -> dict:
    cache = work / "cache_together"
    procs, t0 = [], time.perf_counter()
    for i in range(n):
        out = work / f"together_{i}"
        log = open(work / f"together_{i}.log", "w")
        procs.append((subprocess.Popen(_convsynth([*BASE, f"hydra.run.dir={out}"]), stdout=log,
                                       stderr=subprocess.STDOUT, env=_env(cache), cwd=work), out, log))
    codes = []
    for p, _, log in procs:
        codes.append(p.wait())
        log.close()
    logs = "".join((work / f"together_{i}.log").read_text() for i in range(n))
    tables = [_digest(out / "cooccurrence.csv") for _, out, _ in procs]
    return {"processes": n, "succeeded": sum(c == 0 for c in codes), "exit_codes": codes,
            "identical_tables": len(set(tables)) == 1 and tables[0] is not None,
            "corpus_generated": logs.count("generating synthetic corpus"),
            "wall_s": round(time.perf_counter() - t0, 1), "cache": cache_report(cache),
            "errors": [line for line in logs.splitlines() if "ERROR" in line or "Error" in line][:10]}


def multirun(work: Path) -> dict:
    import pandas as pd

    cache = work / "cache_multirun"
    sweep = work / "multirun"
    t0 = time.perf_counter()
    with open(work / "multirun.log", "w") as log:
        code = subprocess.call(_convsynth(["-m", *BASE, "hydra/launcher=joblib", "hydra.launcher.n_jobs=4",
                                           "stats.n_permutations=200,300,400,500", f"hydra.sweep.dir={sweep}"]),
                               stdout=log, stderr=subprocess.STDOUT, env=_env(cache), cwd=work)
    logs = (work / "multirun.log").read_text()
    job_logs = "".join(p.read_text() for p in sweep.rglob("*.log"))  # the launcher's output repeats them
    tables = []
    for i in range(4):
        p = sweep / str(i) / "cooccurrence.csv"
        tables.append(pd.read_csv(p)[["character", "hypothesis", "matched", "total"]].to_csv(index=False)
                      if p.is_file() else None)
    return {"jobs": 4, "exit_code": code, "succeeded": sum(t is not None for t in tables),
            "identical_counts": len(set(tables)) == 1 and tables[0] is not None,
            "corpus_generated": job_logs.count("generating synthetic corpus"),
            "wall_s": round(time.perf_counter() - t0, 1), "cache": cache_report(cache),
            "errors": [line for line in logs.splitlines() if "ERROR" in line or "Error" in line][:10]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--processes", type=int, default=4)
    args = ap.parse_args()
    load_before = Path("/proc/loadavg").read_text().split()[:3]
    with tempfile.TemporaryDirectory(prefix="parallel_cache_") as tmp:
        work = Path(tmp)
        result = {"together": together(args.processes, work), "joblib_multirun": multirun(work)}
    result["loadavg_before"] = load_before
    result["loadavg_after"] = Path("/proc/loadavg").read_text().split()[:3]
    write_result("parallel_cache", result, overrides=BASE)


if __name__ == "__main__":
    main()
