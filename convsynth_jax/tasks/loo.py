"""Task ``loo``: one leave-one-out fold in one ablation condition of the configured system.

``convsynth task=loo system=motion_graph fold=3 condition=no_lr`` holds out session 3, fits the
system on the other sessions (models cached in ``cache_dir`` where the system supports it, shared
by all conditions with the same fit), synthesizes both characters in every 15 s window (14 s hop)
of the held-out session and writes ``cases.csv`` (one row per window x character). Errors are
recorded in the table and summary; the job itself does not fail, so a sweep always runs to the end.

Resumable sweeps: a job that succeeds is also kept in the results store ``task.store`` (default
``${cache_dir}/results/loo``) under the hash of its resolved configuration, its corpus's content and the code
(:mod:`convsynth_jax.evaluation.store`). With ``task.resume=true`` (default) a job whose entry is
there copies it into its output folder instead of computing it (``summary.json``: ``resumed``), so
re-running a killed sweep redoes only the jobs that had not finished. Failed jobs are not stored
(a re-run tries them again), nor are jobs with ``task.export_bvh=true`` (their motion files are not
kept in the store). ``task.store=null`` turns the store off.
"""
from __future__ import annotations

import logging
import time
import traceback
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import pandas as pd

from ..evaluation import summaries
from ..utils import atomic_path

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class LooSettings:
    """``conf/task/loo.yaml`` (fold and condition: the top-level ``fold``, ``condition``)."""

    name: str = "loo"
    export_bvh: bool = False            # write each synthesized window as BVH
    store: Optional[str] = None         # results store (evaluation/store.py); None: off
    resume: bool = True                 # reuse a finished job's stored result instead of computing it


# configuration keys that do not change a job's result (left out of its store key)
NOT_IN_KEY = ("cache_dir", "progress", "jax_cache", "path")
NOT_IN_TASK_KEY = ("store", "resume")


def store_key(cfg, corpus_content: str | None = None) -> str:
    """The results-store key of this job: its resolved configuration without :data:`NOT_IN_KEY` (and
    the task's ``store``/``resume``), the content of its corpus (``corpus_content``:
    :func:`convsynth_jax.io.corpus.corpus_fingerprint`; None: the configured corpus, opened here) and the
    package's source fingerprint."""
    from omegaconf import OmegaConf

    from ..evaluation.store import code_fingerprint, job_key

    if corpus_content is None:
        from .common import open_corpus, params_of

        corpus_content = open_corpus(params_of(cfg)).fingerprint()
    config = OmegaConf.to_container(cfg, resolve=True)
    config = {k: v for k, v in config.items() if k not in NOT_IN_KEY and k != "hydra"}
    config["task"] = {k: v for k, v in config.get("task", {}).items() if k not in NOT_IN_TASK_KEY}
    config["corpus_content"] = corpus_content
    return job_key(config, code_fingerprint())


def run(cfg, out_dir: Path) -> dict:
    from ..config import task_settings
    from ..evaluation.store import ResultStore

    settings = task_settings(cfg)
    if settings.store is None or settings.export_bvh:  # the store keeps tables, not the exported motion
        return _run_job(cfg, out_dir, settings)
    try:
        key = store_key(cfg)
    except Exception as e:  # noqa: BLE001  (a corpus that cannot be opened: the job records the error)
        log.error("fold %s: cannot key the job in the results store (%s)", cfg.get("fold"), e)
        return _run_job(cfg, out_dir, settings)
    store = ResultStore(settings.store)
    with store.claim(key):  # the same job started twice at once: computed once
        stored = store.read(key) if settings.resume else None
        if stored is not None:
            log.info("fold %s condition %s: finished before, stored result %s reused", stored.record.get("fold"),
                     stored.record.get("condition"), store.entry(key))
            _write_cases(stored.cases, out_dir)
            return {**stored.record["summary"], "resumed": True, "store_key": key}
        summary = _run_job(cfg, out_dir, settings)
        if summary["success"]:
            import pandas as pd

            store.write(key, pd.read_csv(out_dir / "cases.csv"),
                        {"system": summary["system"], "fold": summary["fold"], "condition": summary["condition"],
                         "summary": summary, "config": _plain(cfg)})
    return {**summary, "resumed": False, "store_key": key}


def _plain(cfg) -> dict:
    from omegaconf import OmegaConf

    return OmegaConf.to_container(cfg, resolve=True)


def _write_cases(cases: pd.DataFrame, out_dir: Path) -> None:
    with atomic_path(out_dir / "cases.csv") as tmp:
        cases.to_csv(tmp, index=False)


def _run_job(cfg, out_dir: Path, settings: LooSettings) -> dict:
    from ..evaluation.loo import run_fold
    from .common import annotated_corpus, cache_dir, make_configured_system, params_of

    fold = int(cfg.get("fold", 0))
    condition = str(cfg.get("condition", "all"))
    system_name = str(cfg.system.name)
    t0 = time.perf_counter()
    try:
        params = params_of(cfg)
        system = make_configured_system(params)
        system.condition_options(condition)
        _, annotations = annotated_corpus(params)
        cases = run_fold(system, annotations, fold, condition, params, out_dir=out_dir, cache_dir=cache_dir(params),
                         export_bvh=settings.export_bvh, with_audio=system.needs_audio)
        error = None
    except Exception as e:  # a failing job is recorded, it does not end the sweep
        log.error("fold %s condition %s failed: %s", fold, condition, e)
        cases = pd.DataFrame([{"system": system_name, "fold": fold, "condition": condition, "status": "error",
                               "success": False, "error": f"{type(e).__name__}: {e}"}])
        error = traceback.format_exc()
    _write_cases(cases, out_dir)
    ok = cases.get("success", pd.Series(dtype=bool)).fillna(False).astype(bool)
    # a window (test case) is solved when every character in it is; a character-window is one row
    windows = summaries.test_cases(cases) if error is None and "window" in cases else pd.DataFrame({"success": []})
    return {
        "system": system_name, "fold": fold, "condition": condition,
        "windows": int(len(windows)), "solved_windows": int(windows["success"].sum()),
        "character_windows": int(len(cases)) if error is None else 0,
        "solved_character_windows": int(ok.sum()), "success": error is None, "error": error,
        "seconds": time.perf_counter() - t0,
    }
