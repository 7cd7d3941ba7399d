"""Task ``collect``: merge a multirun of leave-one-out jobs into one table plus summary tables.

``convsynth task=collect collect.dir=multirun/loo/<timestamp>`` writes ``all_cases.csv``,
``success_rates``, ``table3``, ``cooccurrence_by_condition`` and ``quality_by_condition`` (CSV and
Markdown) into this task's output directory. Failed jobs appear as rows with status ``error``.
``convsynth task=collect task.store=DIR`` reads the results store of resumable sweeps instead (every
finished job kept there, ``convsynth_jax/evaluation/store.py``; the default store of ``task=loo`` is
``${cache_dir}/results/loo``).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Optional

from ..errors import ConfigError
from ..evaluation.collect import collect_cases, write_collected


@dataclass(frozen=True)
class CollectSettings:
    """``conf/task/collect.yaml``."""

    name: str = "collect"
    dir: Optional[str] = None           # a multirun folder of task=loo jobs
    store: Optional[str] = None         # or: a results store (task=loo's task.store)


def run(cfg, out_dir: Path) -> dict:
    from ..config import task_settings

    settings = task_settings(cfg)
    if bool(settings.dir) == bool(settings.store):
        raise ConfigError("collect needs either task.dir=<multirun directory> or task.store=<results store>")
    if settings.store:
        from ..evaluation.store import collect_store

        src, cases = settings.store, collect_store(settings.store)
    else:
        src, cases = settings.dir, collect_cases(settings.dir)
    summary = write_collected(cases, out_dir)
    return {"source": str(src), **summary}
