"""Benchmark: where the test suite's time goes (docs/testing.md, "Where CI time goes").

Runs ``python -m pytest -q`` (the README's test command, in the current environment, with its pytest
options: two xdist workers on a 2-core machine) with the plugin ``_compile_listener.py``, which records every
XLA compilation in the pytest processes by test and jitted function. Prints and writes the suite's wall
time, the CPU time of pytest and every process it started, and the compile time summed over the pytest
processes, with the largest shares by function and by test file. Compilations inside processes that the
tests start (CLI, launcher, cache tests) are not counted. The wall time of one tree varies by up to a
half with the machine's load: compare only back-to-back runs.
Writes experiments/results/bench_test_suite.json and .md.

    python experiments/bench/bench_test_suite.py [--top N] [pytest arguments, e.g. tests/test_search.py]
"""
import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

from convsynth_jax.api import REPO, write_result, write_result_markdown


HERE = Path(__file__).resolve().parent


def largest(rows, key, top):
    """[(name, compilations, seconds)] of the ``top`` largest compile-time shares grouped by ``key``."""
    totals = defaultdict(lambda: [0, 0.0])
    for row in rows:
        t = totals[key(row)]
        t[0] += 1
        t[1] += row[2]
    return [(k, n, round(s, 1)) for k, (n, s) in sorted(totals.items(), key=lambda kv: -kv[1][1])[:top]]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--top", type=int, default=10)
    args, pytest_args = ap.parse_known_args()
    with tempfile.TemporaryDirectory() as out:
        env = dict(os.environ, COMPILE_LISTENER_OUT=out,
                   PYTHONPATH=os.pathsep.join(filter(None, [str(HERE), os.environ.get("PYTHONPATH")])))
        cmd = [sys.executable, "-m", "pytest", "-q", "-p", "_compile_listener", *pytest_args]
        t0 = time.perf_counter()
        r = subprocess.run(cmd, cwd=REPO, env=env, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        children = resource.getrusage(resource.RUSAGE_CHILDREN)
        rows = [tuple(row) for f in sorted(Path(out).glob("*.json")) for row in json.loads(f.read_text())]
    summary = r.stdout.strip().splitlines()[-1] if r.stdout.strip() else ""
    if r.returncode != 0:
        sys.exit(f"pytest exited with {r.returncode}: {summary}\n{r.stdout[-3000:]}{r.stderr[-3000:]}")
    result = {
        "pytest_args": pytest_args, "pytest_summary": summary, "wall_s": round(wall, 1),
        "cpu_s": round(children.ru_utime + children.ru_stime, 1),
        "compilations": len(rows), "compile_s": round(sum(row[2] for row in rows), 1),
        "by_function": largest(rows, lambda row: row[1], args.top),
        "by_file": largest(rows, lambda row: row[0].split("::")[0], args.top),
    }
    write_result("bench_test_suite", result, overrides=pytest_args)
    lines = [f"pytest: {summary}; wall {result['wall_s']} s, CPU {result['cpu_s']} s; XLA compile "
             f"{result['compile_s']} s in {result['compilations']} compilations (pytest processes)", "",
             "| jitted function | compilations | seconds |", "|---|---|---|"]
    lines += [f"| `{name}` | {n} | {s} |" for name, n, s in result["by_function"]]
    lines += ["", "| test file | compilations | seconds |", "|---|---|---|"]
    lines += [f"| `{name}` | {n} | {s} |" for name, n, s in result["by_file"]]
    write_result_markdown("bench_test_suite", lines, overrides=pytest_args)


if __name__ == "__main__":
    main()
