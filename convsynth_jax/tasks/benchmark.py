"""Task ``benchmark``: the field-standard evaluation of every system on the same windows (docs/metrics.md).

``convsynth task=benchmark`` scores the ground truth, the mismatched ground truth and each system of
``task.systems`` (label -> system, condition, optional preset) on the leave-one-out windows of the
configured corpus (``loo.window``/``loo.hop``; ``task.folds``), running the folds it needs or reading
a finished sweep per label from ``task.from_dir``. It writes ``benchmark.csv`` (one row per window x
character x system x scope, every metric, failures as rows), ``leaderboard.csv`` / ``.md`` (value,
bootstrap 95% interval over sessions, rank) and ``leaderboard.png``. Metrics: docs/metrics.md.
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Dict, List, Optional

from omegaconf import OmegaConf

from ..errors import ConfigError
from ..evaluation.field.params import FieldMetricParams
from ..utils import atomic_path, write_text_atomic

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class BenchmarkSystem:
    """One entry of ``task.systems``: a system (``conf/system/<system>.yaml``), its condition and
    an optional preset (``conf/preset/<preset>.yaml``) applied for this entry only."""

    system: str
    condition: str
    preset: Optional[str] = None


def _default_systems() -> dict:
    return {"random_playback": BenchmarkSystem("random_playback", "none"),
            "motion_graph": BenchmarkSystem("motion_graph", "all"),
            "cdbn": BenchmarkSystem("cdbn", "cdbn")}


@dataclass(frozen=True)
class BenchmarkSettings:
    """``conf/task/benchmark.yaml``."""

    name: str = "benchmark"
    systems: Dict[str, Optional[BenchmarkSystem]] = field(default_factory=_default_systems)  # null drops a label
    only: Optional[str] = None
    from_dir: Optional[str] = None
    folds: Optional[List[int]] = None
    autoencoder_corpus: Optional[str] = None
    autoencoder_sessions: int = 4
    autoencoder_seed_offset: int = 1000
    figure: bool = True
    metrics: FieldMetricParams = field(default_factory=FieldMetricParams)


def _conf_file(group: str, name: str) -> Path:
    from ..config import CONFIG_DIR

    path = Path(CONFIG_DIR) / group / f"{name}.yaml"
    if not path.is_file():
        known = sorted(p.stem for p in (Path(CONFIG_DIR) / group).glob("*.yaml") if p.stem != "schema")
        raise ConfigError(f"no {group} {name!r}; {group}s are {known}", where=str(path))
    return path


def system_params(cfg, entry: BenchmarkSystem):
    """The typed parameters of the run with ``system=<entry.system>`` (and ``preset=<entry.preset>``)."""
    from .common import params_of

    c = OmegaConf.create(OmegaConf.to_container(cfg, resolve=False))
    sys_yaml = OmegaConf.load(_conf_file("system", entry.system))
    sys_yaml.pop("defaults", None)
    c.system = sys_yaml
    if entry.preset:
        pre = OmegaConf.load(_conf_file("preset", entry.preset))
        pre.pop("defaults", None)
        c = OmegaConf.merge(c, pre)
    return params_of(c)


def run(cfg, out_dir: Path) -> dict:
    from ..config import task_settings
    from ..evaluation import benchmark as bm
    from ..figures import save_figure
    from ..figures.benchmark import leaderboard_figure
    from ..systems.base import make_system
    from ..api import autoencoder_training
    from .common import annotated_corpus, cache_dir, params_of

    t_start = time.perf_counter()
    task: BenchmarkSettings = task_settings(cfg)
    params = params_of(cfg)
    entries = {k: v for k, v in task.systems.items() if v is not None}   # task.systems.<label>=null drops one
    if task.only is not None:
        if task.only not in entries:
            raise ConfigError(f"task.only={task.only!r} is not a label of task.systems {sorted(entries)}")
        entries = {task.only: entries[task.only]}
    sys_params = {label: system_params(cfg, e) for label, e in entries.items()}
    systems = {label: make_system(p, p.system) for label, p in sys_params.items()}
    for label, s in systems.items():
        s.condition_options(entries[label].condition)   # an unknown condition fails before any work
    _, annotations = annotated_corpus(params)
    fps, loo = params.fps, params.loo
    cases = bm.benchmark_cases(annotations, fps, loo.window, loo.hop, loo.max_windows, task.folds)
    log.info("benchmark: %d windows x characters, systems %s", len(cases), list(entries))
    gt, mm = bm.controls(annotations, cases, fps, loo.window, loo.hop)
    scored = [gt, mm]
    timings = {}
    for label, system in systems.items():
        t0 = time.perf_counter()
        cond = entries[label].condition
        scopes = ("body", "head") if system.produces_hands else ("head",)
        if task.from_dir:
            src = Path(task.from_dir) / label
            if not src.is_dir():
                raise ConfigError(f"task.from_dir has no folder for system {label!r}", where=str(src))
            sm = bm.sweep_motions(src, label, cond, cases, scopes)
        else:
            sm = bm.run_system(system, annotations, cases, cond, sys_params[label], out_dir / "runs" / label,
                               cache_dir=cache_dir(params))
            sm.name = label
        timings[f"{label}_synthesis_s"] = time.perf_counter() - t0
        scored.append(sm)
    t0 = time.perf_counter()
    training, ae_source = autoencoder_training(params, task)
    aes = bm.train_autoencoders(training, task.metrics, params.annotate, ("body", "head"),
                                cache_dir=Path(params.cache_dir) / "metric_autoencoders") if training else {}
    timings["autoencoder_s"] = time.perf_counter() - t0
    audio = {c.key: bm.case_audio(annotations, c, fps) for c in cases}
    t0 = time.perf_counter()
    res = bm.score_benchmark(cases, scored, audio, fps, task.metrics, params.annotate, aes, progress=params.progress)
    timings["metrics_s"] = time.perf_counter() - t0
    with atomic_path(out_dir / "benchmark.csv") as tmp:
        res.rows.to_csv(tmp, index=False)
    with atomic_path(out_dir / "leaderboard.csv") as tmp:
        res.leaderboard.to_csv(tmp, index=False)
    write_text_atomic(out_dir / "leaderboard.md", bm.leaderboard_markdown(res.leaderboard))
    if task.figure and not res.leaderboard.empty:
        save_figure(leaderboard_figure(res.leaderboard), out_dir / "leaderboard.png")
    counts = res.rows.groupby(["system", "scope", "status"]).size()
    return {
        "character_windows": len(cases), "folds": sorted({c.fold for c in cases}), "systems": [s.name for s in scored],
        "sources": {s.name: s.source for s in scored}, "autoencoder_training": ae_source,
        "autoencoder_seconds": {f"{k[0]}_{k[1]}": v.seconds for k, v in aes.items()},
        "status_counts": {"/".join(map(str, k)): int(v) for k, v in counts.items()},
        "timings": {**timings, **res.seconds}, "seconds": time.perf_counter() - t_start,
    }
