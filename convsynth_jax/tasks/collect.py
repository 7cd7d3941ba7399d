"""Task ``collect``: merge a multirun into one table per kind of job plus summary tables.

``convsynth task=collect task.dir=multirun/<task>/<timestamp>`` reads every job of the sweep by its
task (``convsynth_jax/evaluation/collect.py``): leave-one-out (``task=loo``) into ``all_cases.csv``,
``success_rates`` (per condition: windows, solved windows), ``success_by_character`` (character-windows),
``table3``, ``cooccurrence_by_condition`` and ``quality_by_condition``; ``task=converse`` into
``converse_by_condition`` (constraints met per condition and speaker on the constraints of condition
``all``, those a condition switches off reported apart), ``converse_by_kind`` and
``converse_speakers``; ``task=benchmark`` into ``leaderboard`` and ``leaderboard_wide``;
``task=walktalk_eval`` into ``walktalk``; ``task=cdbn_eval`` into ``cdbn_head`` (and its gesture and
hand tables). Each table as CSV and Markdown, ``jobs.csv`` (one row per job: kind, status, error,
overrides), and the main table printed. Failed jobs appear with status ``error`` and are counted in
``num_failed_jobs``. ``convsynth task=collect task.store=DIR`` reads the results store of resumable
leave-one-out sweeps instead (``convsynth_jax/evaluation/store.py``; the default store of
``task=loo`` is ``${cache_dir}/results/loo``).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Optional

from ..errors import ConfigError
from ..evaluation.collect import collect_cases, collect_sweep, write_collected


@dataclass(frozen=True)
class CollectSettings:
    """``conf/task/collect.yaml``."""

    name: str = "collect"
    dir: Optional[str] = None           # a multirun folder (any task the collection knows)
    store: Optional[str] = None         # or: a results store (task=loo's task.store)


def run(cfg, out_dir: Path) -> dict:
    from ..config import task_settings

    settings = task_settings(cfg)
    if bool(settings.dir) == bool(settings.store):
        raise ConfigError("collect needs either task.dir=<multirun directory> or task.store=<results store>")
    if settings.store:
        from ..evaluation.store import collect_store

        summary = write_collected(collect_store(settings.store), out_dir)
        return {"source": str(Path(settings.store).resolve()), **summary}
    sweep = collect_sweep(settings.dir)
    loo = "loo" in sweep.kinds or not sweep.kinds
    summary = write_collected(collect_cases(settings.dir, sweep) if loo else _no_cases(), out_dir, sweep)
    figures = _figures(out_dir)
    return {"source": str(Path(settings.dir).resolve()), **summary, "figures": figures}


def _figures(out_dir: Path) -> list[str]:
    """The main table's figure, where there is one: success rates (leave-one-out), constraints met per
    condition (converse), the leaderboard (benchmark)."""
    import pandas as pd

    from ..figures import save_figure

    made = []
    if (out_dir / "success_rates.csv").is_file() and (out_dir / "success_rates.csv").stat().st_size > 1:
        from ..figures.motion_graph import success_rate_figure

        rates = pd.read_csv(out_dir / "success_rates.csv")
        if len(rates):
            made.append(save_figure(success_rate_figure(rates), out_dir / "success_rates.png", dpi=120).name)
    if (out_dir / "converse_by_condition.csv").is_file():
        from ..figures.converse import converse_conditions_figure

        t = pd.read_csv(out_dir / "converse_by_condition.csv")
        if len(t):
            made.append(save_figure(converse_conditions_figure(t), out_dir / "converse_by_condition.png", dpi=120).name)
    if (out_dir / "leaderboard.csv").is_file():
        from ..figures.benchmark import leaderboard_figure

        board = pd.read_csv(out_dir / "leaderboard.csv")
        if len(board):
            made.append(save_figure(leaderboard_figure(board), out_dir / "leaderboard.png", dpi=110).name)
    return made


def _no_cases():
    import pandas as pd

    return pd.DataFrame()
