"""Task ``study_analyze``: Figure 6 from a study's exported answers (paper Section 8.2).

``convsynth task=study_analyze task.answers=export.csv task.study=DIR``: participants who chose the
frozen side in more than ``task.max_failed_attention`` attention checks are excluded (and counted),
answers are counted per pair of the study's manifest, and each pair is tested as ``task=user_study``
does (:func:`convsynth_jax.study.analyze.forced_choice_table`: prop.test with continuity correction,
exact binomial). Writes ``study_counts.csv`` (the counts and tests), ``attention.csv``,
``figure6.png`` and ``report.md``.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

from ..errors import ConfigError
from ..utils import atomic_path, write_text_atomic

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class StudyAnalyzeSettings:
    """``conf/task/study_analyze.yaml``."""

    name: str = "study_analyze"
    answers: Optional[str] = None        # the CSV of /admin/export.csv
    study: Optional[str] = None          # the study folder (its manifest names the pairs)
    max_failed_attention: int = 0        # a participant failing more attention checks is excluded


def run(cfg, out_dir: Path) -> dict:
    from ..config import task_settings
    from ..evaluation.summaries import to_markdown
    from ..figures import save_figure
    from ..figures.motion_graph import figure6_figure
    from ..study import design
    from ..study.analyze import analyze_answers, read_answers
    from ..study.build import load_study_manifest
    from .common import params_of

    s = task_settings(cfg)
    if not s.answers or not s.study:
        raise ConfigError("task=study_analyze needs task.answers=CSV and task.study=DIR", where="task")
    manifest = load_study_manifest(s.study)
    pairs = design.pairs_from_config(manifest["study"]["pairs"])
    answers = read_answers(s.answers)
    unknown = set(answers["stimulus"]) - {x["id"] for x in manifest["stimuli"]}
    if unknown:
        raise ConfigError(f"answers name stimuli the study does not have: {sorted(unknown)[:5]}", where="task.answers")
    alpha = params_of(cfg).stats.significance
    table, att = analyze_answers(answers, pairs, alpha=alpha, max_failed=s.max_failed_attention)
    with atomic_path(out_dir / "study_counts.csv") as tmp:
        table.to_csv(tmp, index=False)
    with atomic_path(out_dir / "attention.csv") as tmp:
        att.to_csv(tmp, index=False)
    if len(table):
        save_figure(figure6_figure(table), out_dir / "figure6.png", dpi=120)
    excluded = int(att["excluded"].sum())
    cols = [c for c in ("comparison", "preferred_a", "total", "share_a", "chi2", "p_value", "binom_p", "significant") if c in table]
    lines = ["# Forced-choice study: Figure 6", "",
             f"Answers: {len(answers)} from {att['participant'].nunique()} participants; excluded for failing attention "
             f"checks (more than {s.max_failed_attention} failed): {excluded}.", "",
             "Per pair: answers preferring the first condition of all answers; R's prop.test with continuity correction "
             f"(as the paper) and the exact binomial test of 1/2; significant: prop.test p < {alpha}.", "",
             to_markdown(table[cols]) if len(table) else "(no answers to regular trials)", "", "![Figure 6](figure6.png)", ""]
    write_text_atomic(out_dir / "report.md", "\n".join(lines))
    log.info("%s", "\n" + (to_markdown(table[cols]) if len(table) else "no answers"))
    return {"answers": int(len(answers)), "participants": int(att["participant"].nunique()), "excluded": excluded,
            "rows": table.to_dict(orient="records")}
