"""Task ``loo``: one leave-one-out fold in one ablation condition of the configured system.

``convsynth task=loo system=motion_graph fold=3 condition=no_lr`` holds out session 3, fits the
system on the other sessions (models cached in ``cache_dir`` where the system supports it, shared
by all conditions with the same fit), synthesizes both characters in every 15 s window (14 s hop)
of the held-out session and writes ``cases.csv`` (one row per window x character). Errors are
recorded in the table and summary; the job itself does not fail, so a sweep always runs to the end.
"""
from __future__ import annotations

import logging
import time
import traceback
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from ..utils import atomic_path

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class LooSettings:
    """``conf/task/loo.yaml`` (fold and condition: the top-level ``fold``, ``condition``)."""

    name: str = "loo"
    export_bvh: bool = False            # write each synthesized window as BVH


def run(cfg, out_dir: Path) -> dict:
    from ..config import task_settings
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
                         export_bvh=task_settings(cfg).export_bvh,
                         with_audio=system.needs_audio)
        error = None
    except Exception as e:  # a failing job is recorded, it does not end the sweep
        log.error("fold %s condition %s failed: %s", fold, condition, e)
        cases = pd.DataFrame([{"system": system_name, "fold": fold, "condition": condition, "status": "error",
                               "success": False, "error": f"{type(e).__name__}: {e}"}])
        error = traceback.format_exc()
    with atomic_path(out_dir / "cases.csv") as tmp:
        cases.to_csv(tmp, index=False)
    ok = cases.get("success", pd.Series(dtype=bool)).fillna(False).astype(bool)
    return {
        "system": system_name, "fold": fold, "condition": condition, "num_cases": int(len(cases)),
        "num_success": int(ok.sum()), "success": error is None, "error": error,
        "seconds": time.perf_counter() - t0,
    }
