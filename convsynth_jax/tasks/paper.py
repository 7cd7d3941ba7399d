"""Task ``paper``: every paper table and figure regenerated from results files, the paper's values beside.

``convsynth task=paper path=RUN [task.sweep=DIR]`` reads the tables a finished main run wrote (RUN:
``table1_cooccurrence.csv``, ``table2.csv``, ``figure4_histograms.csv``, ``figure4_fits.csv``,
``cases.csv``) and, with ``task.sweep``, the ``all_cases.csv`` of a collected leave-one-out sweep
(``task=collect``) for the leave-one-out artifacts (success rates, Table 3, the co-occurrence ablation,
motion quality) instead of the run's one held-out fold. It writes into its output folder ``report.md``
and each artifact's CSV and PNG: the paper sections of the main job's ``report.md`` (Table 1, Table 2,
Figure 4, Table 3, success rates, the ablation, Figure 6 re-tested, motion quality), made by the same
code from the files alone; nothing of the pipeline is computed again. For the main job's own run its
``report.md`` already is this; the command redraws it after a sweep, or after a change of a figure.
``experiments/paper/*.py`` draw one artifact each from the same files.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import pandas as pd

from ..errors import ConfigError, MissingFileError


@dataclass(frozen=True)
class PaperSettings:
    """``conf/task/paper.yaml``."""

    name: str = "paper"
    sweep: Optional[str] = None   # a task=collect folder of a leave-one-out sweep (its all_cases.csv)


def _read(folder: Path, name: str, required: bool = True) -> pd.DataFrame | None:
    f = folder / name
    if not f.is_file():
        if required:
            raise MissingFileError(f"{name} not found (written by the main job, `convsynth`)", f)
        return None
    return pd.read_csv(f)


def run(cfg, out_dir: Path) -> dict:
    from ..config import task_settings
    from ..evaluation import summaries
    from ..evaluation.runs import read_summary
    from ..utils import write_text_atomic
    from .common import params_of
    from .main import TABLE2_COLUMNS, _paper_sections

    settings = task_settings(cfg)
    if not cfg.get("path"):
        raise ConfigError("task=paper needs path=RUN, a finished main run (outputs/main/<stamp>)")
    run_dir = Path(cfg.path).resolve()
    run_summary = read_summary(run_dir)
    table1 = _read(run_dir, "table1_cooccurrence.csv")
    t2, hist, fits = (_read(run_dir, n, required=False) for n in ("table2.csv", "figure4_histograms.csv", "figure4_fits.csv"))
    graph_stats = None
    if t2 is not None and hist is not None and fits is not None:
        graph_stats = (t2[[c for c in TABLE2_COLUMNS if c in t2]], hist, fits.drop(columns=["w_v"], errors="ignore"))
    if settings.sweep:
        src = Path(settings.sweep).resolve() / "all_cases.csv"
        cases = _read(src.parent, src.name)
    else:
        src = run_dir / "cases.csv"
        cases = _read(run_dir, "cases.csv")
    ok = cases[cases["status"] != "error"] if "status" in cases else cases
    rates = summaries.success_rates(ok)
    co = summaries.cooccurrence_by_condition(ok)
    timing = summaries.timing_table(ok)
    sections = _paper_sections(out_dir, table1, graph_stats, timing, rates, co, ok, params_of(cfg).stats.significance)
    head = ["# Paper artifacts from results files", "",
            f"Main run: `{run_dir}` (corpus `{run_summary.get('corpus_root')}`, held-out session "
            f"`{run_summary.get('held_out_session')}`). Leave-one-out artifacts from `{src}` "
            f"({ok['fold'].nunique() if 'fold' in ok else '?'} folds, {len(ok)} character-windows). "
            "The paper's values (Yang et al. 2020, `convsynth_jax/paper_values.py`) stand in the `paper_*` "
            "columns and the orange bars.", ""]
    write_text_atomic(out_dir / "report.md", "\n".join(head + sections) + "\n")
    print("Success rates\n" + summaries.to_markdown(rates))
    written = sorted(p.name for p in out_dir.iterdir() if p.suffix in (".csv", ".png", ".md"))
    return {"success": True, "run": str(run_dir), "leave_one_out": str(src), "files": written}
