"""Task ``collect``: merge a multirun of leave-one-out jobs into one table plus summary tables.

``convsynth task=collect collect.dir=multirun/loo/<timestamp>`` writes ``all_cases.csv``,
``success_rates``, ``table3``, ``cooccurrence_by_condition`` and ``quality_by_condition`` (CSV and
Markdown) into this task's output directory. Failed jobs appear as rows with status ``error``.
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


def run(cfg, out_dir: Path) -> dict:
    from ..config import task_settings

    src = task_settings(cfg).dir
    if not src:
        raise ConfigError("collect needs task.dir=<multirun directory>")
    cases = collect_cases(src)
    summary = write_collected(cases, out_dir)
    return {"source": str(src), **summary}
