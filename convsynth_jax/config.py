"""Hydra entry point of the ``convsynth`` command. Only this module and ``tasks/`` import Hydra.

``convsynth task=NAME ...`` composes ``conf/config.yaml``, then calls
``convsynth_jax.tasks.NAME.run(cfg, out_dir)``, which returns a summary dict; the summary is written
as ``summary.json`` into Hydra's output directory (``conf/hydra/`` decides where that is).

Typed parameters: every config group has a frozen dataclass (``GROUPS``: the pipeline's groups,
``cdbn``, ``walktalk``, ``loo``, ``jax_cache``; ``TASKS``: each task's settings, ``cfg.task``), and
one function converts it, :func:`convsynth_jax.schema.build_params` (unknown and mistyped keys are
a ConfigError naming the key). :func:`to_params` converts a composed config into
:class:`convsynth_jax.params.Params` once, at the task boundary; :func:`task_settings` converts the
task's settings. The pipeline's groups (``SCHEMA_GROUPS``) are also registered here as Hydra
structured-config schemas named ``schema`` in their group; their YAML files extend it
(``defaults: [schema, _self_]``), so command-line overrides of keys the YAML does not list work and
keys are checked already when the config is composed. Only this module and ``tasks/`` know
OmegaConf: the library receives the dataclasses.
"""
from __future__ import annotations

import importlib
import logging
import os
import time
from pathlib import Path

import hydra
from hydra.core.config_store import ConfigStore
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig, ListConfig, OmegaConf

from .errors import ConfigError, ConvSynthError
from .schema import build_params
from .utils import write_error, write_json_atomic

log = logging.getLogger("convsynth_jax")

# conf/ lives at the top of the repository (design card); convsynth_jax/conf links to it and is
# shipped inside the wheel, so editable and regular installs find it here.
CONFIG_DIR = str(Path(__file__).resolve().parent / "conf")

# config key -> "module:Dataclass" of its typed parameters (systems add theirs here)
GROUPS = {
    "corpus": "convsynth_jax.params:CorpusParams",
    "features": "convsynth_jax.graph.params:FeatureParams",
    "annotate": "convsynth_jax.annotate.params:AnnotateParams",
    "stats": "convsynth_jax.stats.params:StatsParams",
    "graph": "convsynth_jax.graph.params:GraphParams",
    "search": "convsynth_jax.search.params:SearchParams",
    "synth": "convsynth_jax.synth.params:SynthParams",
    "system": "convsynth_jax.systems.base:SystemParams",
    "cdbn": "convsynth_jax.cdbn.params:CDBNParams",
    "walktalk": "convsynth_jax.walktalk.params:WalkTalkParams",
    "loo": "convsynth_jax.params:LooParams",
    "jax_cache": "convsynth_jax.kernel_cache:JaxCacheParams",
}
# groups whose conf/<group>/*.yaml extend a registered structured-config schema
SCHEMA_GROUPS = ("corpus", "features", "annotate", "stats", "graph", "search", "synth", "system")
# task name (conf/task/<name>.yaml) -> "module:Dataclass" of its settings (``cfg.task``), defined beside
# the task's run()
TASKS = {
    "benchmark": "convsynth_jax.tasks.benchmark:BenchmarkSettings",
    "build_graph": "convsynth_jax.tasks.build_graph:BuildGraphSettings",
    "build_graph_sharded": "convsynth_jax.tasks.build_graph_sharded:BuildGraphShardedSettings",
    "cdbn_eval": "convsynth_jax.tasks.cdbn_eval:CDBNEvalSettings",
    "cdbn_make_data": "convsynth_jax.tasks.cdbn_make_data:CDBNMakeDataSettings",
    "cdbn_synthesize": "convsynth_jax.tasks.cdbn_synthesize:CDBNSynthesizeSettings",
    "collect": "convsynth_jax.tasks.collect:CollectSettings",
    "converse": "convsynth_jax.tasks.converse:ConverseParams",
    "convert": "convsynth_jax.tasks.convert:ConvertSettings",
    "cooccurrence": "convsynth_jax.tasks.cooccurrence:CooccurrenceSettings",
    "figure4": "convsynth_jax.tasks.figure4:Figure4Settings",
    "inspect": "convsynth_jax.tasks.inspect:InspectSettings",
    "loo": "convsynth_jax.tasks.loo:LooSettings",
    "main": "convsynth_jax.tasks.main:MainSettings",
    "make_corpus": "convsynth_jax.tasks.make_corpus:MakeCorpusSettings",
    "make_scale_db": "convsynth_jax.tasks.make_scale_db:MakeScaleDBSettings",
    "notebooks": "convsynth_jax.tasks.notebooks:NotebooksSettings",
    "paper": "convsynth_jax.tasks.paper:PaperSettings",
    "render": "convsynth_jax.tasks.render:RenderSettings",
    "study_analyze": "convsynth_jax.tasks.study_analyze:StudyAnalyzeSettings",
    "study_build": "convsynth_jax.tasks.study_build:StudyBuildSettings",
    "study_serve": "convsynth_jax.tasks.study_serve:StudyServeSettings",
    "synthesize": "convsynth_jax.tasks.synthesize:SynthesizeSettings",
    "table2": "convsynth_jax.tasks.table2:Table2Settings",
    "user_study": "convsynth_jax.tasks.user_study:UserStudySettings",
    "view": "convsynth_jax.tasks.view:ViewSettings",
    "walktalk_demo": "convsynth_jax.tasks.walktalk_demo:WalkTalkDemoSettings",
    "walktalk_eval": "convsynth_jax.tasks.walktalk_eval:WalkTalkEvalSettings",
}


def _load(spec: str):
    mod, _, attr = spec.partition(":")
    return getattr(importlib.import_module(mod), attr)


def _writable(node) -> None:
    """Clear the read-only flag OmegaConf sets on frozen dataclasses, so YAML and command-line
    overrides can be merged into the schema (the converted parameters are frozen again)."""
    node._set_flag("readonly", None)
    if isinstance(node, DictConfig):
        for k in node:
            _writable(node._get_node(k))
    elif isinstance(node, ListConfig):
        for i in range(len(node)):
            _writable(node._get_node(i))


def schema_node(cls) -> DictConfig:
    node = OmegaConf.structured(cls)
    _writable(node)
    return node


def register_schemas() -> None:
    cs = ConfigStore.instance()
    for group in SCHEMA_GROUPS:
        cs.store(group=group, name="schema", node=schema_node(_load(GROUPS[group])))


register_schemas()


def _container(node, where: str):
    try:
        return OmegaConf.to_container(node, resolve=True, throw_on_missing=True)
    except Exception as e:  # an unresolvable interpolation or a missing value (omegaconf names the key)
        raise ConfigError(f"invalid {where} config: {e}") from None


def group_params(cfg: DictConfig, group: str):
    """The frozen dataclass of one config group (``cfg[group]`` converted and type-checked)."""
    node = cfg.get(group)
    if node is None:
        raise ConfigError(f"the config has no group {group!r}")
    return build_params(_load(GROUPS[group]), _container(node, group), group)


def to_params(cfg: DictConfig):
    """Convert a composed config into the typed :class:`~convsynth_jax.params.Params` tree (groups
    absent from ``cfg`` take their defaults)."""
    from .params import Params

    groups = {g: group_params(cfg, g) for g in GROUPS if cfg.get(g) is not None}
    top = {k: cfg.get(k) for k in ("seed", "cache_dir", "progress") if cfg.get(k) is not None}
    return build_params(Params, {**top, **groups}, "config")


def task_settings(cfg: DictConfig):
    """The typed settings of the task ``cfg.task.name`` (its dataclass in ``TASKS``)."""
    name = cfg.task.name
    if name not in TASKS:
        raise ConfigError(f"unknown task {name!r}; tasks are {sorted(TASKS)}")
    return build_params(_load(TASKS[name]), _container(cfg.task, "task"), "task")


def run_task(cfg: DictConfig, out_dir: str | Path) -> dict:
    """Run the task named by ``cfg.task.name`` and write ``summary.json`` into ``out_dir``."""
    out_dir = Path(out_dir)
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise write_error(e, out_dir) from None
    name = cfg.task.name
    try:
        module = importlib.import_module(f"convsynth_jax.tasks.{name}")
    except ModuleNotFoundError as e:
        if e.name and e.name.endswith(f"tasks.{name}"):
            raise ConfigError(f"unknown task {name!r}") from None
        raise
    from . import kernel_cache

    task_settings(cfg)  # unknown or mistyped task keys fail before any work
    check_composed(cfg)  # and the system's conditions
    kernel_cache.enable_compilation_cache(group_params(cfg, "jax_cache") if cfg.get("jax_cache") is not None else None)
    t0 = time.perf_counter()
    summary = module.run(cfg, out_dir) or {}
    summary = {"task": name, **summary, "task_seconds": time.perf_counter() - t0}
    write_json_atomic(out_dir / "summary.json", summary)
    return summary


@hydra.main(version_base="1.3", config_path=CONFIG_DIR, config_name="config")
def main(cfg: DictConfig) -> dict | None:
    out_dir = HydraConfig.get().runtime.output_dir
    try:
        summary = run_task(cfg, out_dir)
    except ConvSynthError as e:
        log.error("%s", e)
        try:
            write_json_atomic(Path(out_dir) / "summary.json",
                              {"task": cfg.task.name, "success": False, "error": str(e)})
        except ConvSynthError as e2:  # e.g. the output folder itself cannot be written
            log.error("%s", e2)
        if os.environ.get("CONVSYNTH_RAISE", "1") != "0":
            raise SystemExit(2) from e
        return None
    log.info("wrote %s", Path(out_dir) / "summary.json")
    return summary


def compose(overrides: list[str] | None = None) -> DictConfig:
    """Compose the primary config without running (for notebooks and tests)."""
    from hydra import compose as _compose, initialize_config_dir

    with initialize_config_dir(version_base="1.3", config_dir=CONFIG_DIR):
        cfg = _compose(config_name="config", overrides=list(overrides or []))
    check_composed(cfg)
    return cfg


def check_composed(cfg: DictConfig) -> None:
    """The checks Hydra's schemas cannot make when a config is composed: each ablation condition of the
    system converted to the system's typed condition (``SystemParams``), so a mistyped value or an
    unknown key (``system.conditions.no_lr.use_lr=nope``) is a ConfigError naming the key."""
    if cfg.get("system") is not None:
        group_params(cfg, "system")


def default_params(overrides: list[str] | None = None):
    """The typed parameters of the shipped config with ``overrides`` (for notebooks, tests and the API)."""
    return to_params(compose(overrides))


if __name__ == "__main__":  # pragma: no cover
    main()
