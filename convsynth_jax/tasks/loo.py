"""Task ``loo``: one leave-one-out fold in one ablation condition.

``convsynth experiment=loo fold=3 condition=no_lr`` holds out session 3, builds each character's
graph from the other sessions (cached per fold in ``cache_dir``, shared by all conditions),
synthesizes both characters in every 15 s window (14 s hop) of the held-out session and writes
``cases.csv`` (one row per window x character). Errors are recorded in the table and summary; the
job itself does not fail, so a sweep always runs to the end.
"""
from __future__ import annotations

import logging
import time
import traceback
from pathlib import Path

import pandas as pd

from ..utils import atomic_path

log = logging.getLogger(__name__)


def run(cfg, out_dir: Path) -> dict:
    from ..evaluation.loo import annotate_corpus_cached, run_fold
    from .common import open_corpus

    fold = int(cfg.get("fold", 0))
    condition = str(cfg.get("condition", "all"))
    t0 = time.perf_counter()
    try:
        corpus = open_corpus(cfg)
        cache = Path(cfg.cache_dir) / "loo_cache"
        annotations = annotate_corpus_cached(corpus, cfg, cache)
        cases = run_fold(corpus, annotations, fold, condition, cfg, out_dir=out_dir, cache_dir=cache,
                         export_bvh=bool(cfg.task.get("export_bvh", False)))
        error = None
    except Exception as e:  # a failing job is recorded, it does not end the sweep
        log.error("fold %s condition %s failed: %s", fold, condition, e)
        cases = pd.DataFrame([{"fold": fold, "condition": condition, "status": "error", "success": False,
                               "error": f"{type(e).__name__}: {e}"}])
        error = traceback.format_exc()
    with atomic_path(out_dir / "cases.csv") as tmp:
        cases.to_csv(tmp, index=False)
    ok = cases.get("success", pd.Series(dtype=bool)).fillna(False).astype(bool)
    return {
        "fold": fold, "condition": condition, "num_cases": int(len(cases)),
        "num_success": int(ok.sum()), "success": error is None, "error": error,
        "seconds": time.perf_counter() - t0,
    }
