"""Task ``study_build``: the stimuli of a forced-choice study (paper Section 8.1) from the configured
corpus and system.

``convsynth task=study_build [task.segments=20] [task.sweep=DIR] [task.folds=[0,3]]`` chooses
``task.segments`` leave-one-out windows solved in every condition the pairs compare (seeded; with
``task.sweep``, only windows the sweep's ``cases.csv`` files show solved in all of them), renders one
side-by-side video per (segment, pair) plus ``task.attention_stimuli`` attention checks, and writes
the study folder (:mod:`convsynth_jax.study.build`) into ``study/`` of the run directory (or
``task.out``). ``task=study_serve task.study=<that folder>`` serves it.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, List, Optional

import pandas as pd

from ..errors import ConfigError, FormatError

log = logging.getLogger(__name__)

PAPER_PAIRS = [
    {"name": "gt_vs_all", "a": "ground_truth", "b": "all", "label_a": "Motion capture", "label_b": "All constraints"},
    {"name": "all_vs_no_lr", "a": "all", "b": "no_lr", "label_a": "All constraints", "label_b": "Without LR"},
    {"name": "all_vs_no_hp", "a": "all", "b": "no_hp", "label_a": "All constraints", "label_b": "Without HP"},
    {"name": "all_vs_none", "a": "all", "b": "none", "label_a": "All constraints", "label_b": "No constraints"},
]


@dataclass(frozen=True)
class StudyBuildSettings:
    """``conf/task/study_build.yaml``."""

    name: str = "study_build"
    pairs: List[Any] = field(default_factory=lambda: [dict(p) for p in PAPER_PAIRS])
    segments: int = 20                     # the paper's 20
    repetitions: int = 10                  # the paper's 10 answers per stimulus (the server's target)
    trials_per_participant: int = 20       # the paper's 20 rounds
    attention_stimuli: int = 2             # ours: attention-check videos (ground truth beside it frozen)
    attention_per_participant: int = 2     # ours: mixed into each participant's trials
    folds: Optional[List[int]] = None      # held-out sessions to draw windows from (null: all)
    sweep: Optional[str] = None            # a finished sweep's folder: only windows its cases.csv solved everywhere
    out: Optional[str] = None              # the study folder (null: study/ in the run directory)
    panel_width: int = 320
    panel_height: int = 360
    render_fps: float = 15.0
    yaw_deg: float = 35.0
    pitch_deg: float = 12.0

    def __post_init__(self):
        if self.segments < 1 or self.repetitions < 1 or self.trials_per_participant < 1:
            raise ConfigError("segments, repetitions and trials_per_participant must be positive", where="task")
        if self.attention_stimuli < 0 or self.attention_per_participant < 0:
            raise ConfigError("attention counts must be >= 0", where="task")
        if self.attention_per_participant > self.attention_stimuli:
            raise ConfigError(f"attention_per_participant={self.attention_per_participant} exceeds the "
                              f"{self.attention_stimuli} attention stimuli", where="task.attention_per_participant")


def sweep_cases(folder: str | Path) -> pd.DataFrame:
    """Every ``cases.csv`` below ``folder`` (a sweep's output), concatenated."""
    root = Path(folder)
    files = sorted(root.rglob("cases.csv")) if root.is_dir() else []
    if not files:
        from ..errors import MissingFileError

        raise MissingFileError("no cases.csv below the sweep folder (task.sweep)", root)
    parts = []
    for f in files:
        try:
            parts.append(pd.read_csv(f))
        except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as e:
            raise FormatError(f"not a readable cases.csv ({e})", f) from None
    return pd.concat(parts, ignore_index=True)


def run(cfg, out_dir: Path) -> dict:
    from ..config import task_settings
    from ..study import design
    from ..study.build import build_study
    from .common import annotated_corpus, cache_dir, make_configured_system, params_of

    s = task_settings(cfg)
    params = params_of(cfg)
    pairs = design.pairs_from_config(s.pairs)
    system = make_configured_system(params)
    for c in design.conditions_needed(pairs):
        if c not in system.conditions:
            raise ConfigError(f"pair condition {c!r} is not a condition of system {system.name!r} "
                              f"({sorted(system.conditions)} or {design.GROUND_TRUTH!r})", where="task.pairs")
    _, annotations = annotated_corpus(params)
    target = Path(s.out) if s.out else out_dir / "study"
    settings = {"repetitions": s.repetitions, "trials_per_participant": s.trials_per_participant,
                "attention_per_participant": s.attention_per_participant, "corpus": params.corpus.name or params.corpus.kind}
    m = build_study(system, annotations, params, target, pairs=pairs, segments=s.segments, attention=s.attention_stimuli,
                    seed=int(params.seed), folds=s.folds, sweep_cases=sweep_cases(s.sweep) if s.sweep else None,
                    cache_dir=cache_dir(params), width=s.panel_width, height=s.panel_height, render_fps=s.render_fps,
                    yaw_deg=s.yaw_deg, pitch_deg=s.pitch_deg, settings=settings)
    stim = m["stimuli"]
    needed = design.participants_needed(stim, s.repetitions, s.trials_per_participant)
    log.info("study folder %s: %d stimuli; %d participants give every stimulus %d answers", target, len(stim), needed,
             s.repetitions)
    return {"study": str(target), "num_stimuli": len(stim), "num_attention": sum(x["kind"] == "attention" for x in stim),
            "participants_needed": needed, "rejected_windows": len(m["rejected_windows"]), "timings": m["timings"]}
