"""Resumable sweeps: a leave-one-out sweep killed with SIGKILL during its third job (which waits
for its key's lock, held by the test, so the kill never races the job), run again, computes only the
jobs that had not finished, and ``task=collect task.store=...`` gives the
same table as an uninterrupted sweep's."""
from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

from convsynth_jax.evaluation.store import ResultStore

TIMING = ["fit_seconds", "synthesis_seconds"]


def _convsynth(args):
    exe = shutil.which("convsynth") or str(Path(sys.executable).parent / "convsynth")
    return [exe, *args]


def _collected(store: Path, out: Path) -> pd.DataFrame:
    from convsynth_jax.config import compose, run_task

    run_task(compose(["task=collect", f"task.store={store}"]), out)
    df = pd.read_csv(out / "all_cases.csv").drop(columns=TIMING)
    return df.sort_values(["job_key", "window", "role"]).reset_index(drop=True)


@pytest.mark.slow
def test_killed_sweep_resumes_only_the_missing_jobs(tmp_path, tiny_corpus_dir, tiny_cache_dir):
    cache = tiny_cache_dir("resume_cache")
    env = {**os.environ, "HYDRA_FULL_ERROR": "1"}
    # 4 small jobs (2 folds x 2 seeds, one window each); the three sweeps share the test run's
    # compilation cache (CONVSYNTH_JAX_CACHE, tests/conftest.py)
    sweep = ["-m", "experiment=loo_tiny", "system=random_playback", "condition=none", "fold=0,1", "seed=0,1",
             "loo.max_windows=1", f"corpus.root={tiny_corpus_dir}", f"cache_dir={cache}", "progress=false",
             "jax_cache.kernel_dir=null"]

    full = subprocess.run(_convsynth([*sweep, f"task.store={tmp_path / 'store_full'}", f"hydra.sweep.dir={tmp_path / 'full'}"]),
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert full.returncode == 0, full.stderr[-3000:]
    assert len(ResultStore(tmp_path / "store_full").keys()) == 4

    # the jobs' keys in sweep order (Hydra numbers the jobs of a sweep the same way every time; the key
    # leaves out the store, the cache and Hydra's folders, so each job has the same key in every sweep)
    keys = [json.loads((tmp_path / "full" / str(i) / "summary.json").read_text())["store_key"] for i in range(4)]
    assert len(set(keys)) == 4

    # the third job waits for its key's lock, held here, so the kill lands in it whatever the timing:
    # exactly the first two jobs are finished
    store = tmp_path / "store"
    with ResultStore(store).claim(keys[2]):
        killed = subprocess.Popen(_convsynth([*sweep, f"task.store={store}", f"hydra.sweep.dir={tmp_path / 'first'}"]),
                                  cwd=tmp_path, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        deadline = time.monotonic() + 600
        # Hydra makes a job's folder when the job starts; the second job's entry is complete when it is listed
        while not ((tmp_path / "first" / "2").is_dir() and len(ResultStore(store).keys()) == 2):
            assert killed.poll() is None and time.monotonic() < deadline, "the sweep ended before its third job"
            time.sleep(0.01)
        killed.send_signal(signal.SIGKILL)
        killed.wait()
    done = set(ResultStore(store).keys())
    assert done == set(keys[:2]), (done, keys)

    again = subprocess.run(_convsynth([*sweep, f"task.store={store}", f"hydra.sweep.dir={tmp_path / 'again'}"]),
                           cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert again.returncode == 0, again.stderr[-3000:]
    summaries = [json.loads(p.read_text()) for p in sorted((tmp_path / "again").glob("*/summary.json"))]
    assert len(summaries) == 4 and all(s["success"] for s in summaries)
    assert [s["store_key"] for s in summaries] == keys
    assert [s["resumed"] for s in summaries] == [True, True, False, False]    # finished jobs skipped, only the missing ones run
    assert not [p for p in store.iterdir() if p.name.startswith(".") and p.is_dir()]  # no partial entry left

    pd.testing.assert_frame_equal(_collected(store, tmp_path / "collect"),
                                  _collected(tmp_path / "store_full", tmp_path / "collect_full"))
