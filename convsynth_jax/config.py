"""Hydra entry point of the ``convsynth`` command. Only this module and ``tasks/`` import Hydra.

``convsynth task=NAME ...`` composes ``conf/config.yaml``, then calls
``convsynth_jax.tasks.NAME.run(cfg, out_dir)``, which returns a summary dict; the summary is written
as ``summary.json`` into Hydra's output directory (``conf/hydra/`` decides where that is).

Typed parameters: every config group with parameters has a frozen dataclass (``GROUPS``) that is
registered here as a Hydra structured-config schema named ``schema`` in its group; the group's
YAML files extend it (``defaults: [schema, _self_]``), so keys and types are checked when the config
is composed and the defaults live in the dataclass only. :func:`to_params` converts a composed
config into :class:`convsynth_jax.params.Params` once, at the task boundary.
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
from .utils import write_json_atomic

log = logging.getLogger("convsynth_jax")

# conf/ lives at the top of the repository (design card); convsynth_jax/conf links to it and is
# shipped inside the wheel, so editable and regular installs find it here.
CONFIG_DIR = str(Path(__file__).resolve().parent / "conf")

# config group -> "module:Dataclass" of its typed parameters (systems add theirs here)
GROUPS = {
    "corpus": "convsynth_jax.params:CorpusParams",
    "features": "convsynth_jax.graph.params:FeatureParams",
    "annotate": "convsynth_jax.annotate.params:AnnotateParams",
    "stats": "convsynth_jax.stats.params:StatsParams",
    "graph": "convsynth_jax.graph.params:GraphParams",
    "search": "convsynth_jax.search.params:SearchParams",
    "synth": "convsynth_jax.synth.params:SynthParams",
    "system": "convsynth_jax.systems.base:SystemParams",
}
# groups that are not part of Params' fixed fields go to Params.extra
CORE_GROUPS = ("corpus", "features", "annotate", "stats", "graph", "search", "synth", "system")
# groups of other systems that convert their own parameters (Params.extra[group] is a plain dict)
SYSTEM_GROUPS = ("cdbn", "walktalk")


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
    for group, spec in GROUPS.items():
        cs.store(group=group, name="schema", node=schema_node(_load(spec)))


register_schemas()


def group_params(cfg: DictConfig, group: str):
    """The frozen dataclass of one config group (``cfg[group]`` converted and type-checked)."""
    cls = _load(GROUPS[group])
    node = cfg.get(group)
    if node is None:
        raise ConfigError(f"the config has no group {group!r}")
    try:
        merged = OmegaConf.merge(schema_node(cls), OmegaConf.to_container(node, resolve=True, throw_on_missing=True))
        return OmegaConf.to_object(merged)
    except ConvSynthError:
        raise
    except Exception as e:  # omegaconf's validation errors name the key
        raise ConfigError(f"invalid {group} config: {e}") from None


def to_params(cfg: DictConfig):
    """Convert a composed config into the typed :class:`~convsynth_jax.params.Params` tree."""
    from .params import LooParams, Params

    core = {g: group_params(cfg, g) for g in CORE_GROUPS}
    extra = {g: group_params(cfg, g) for g in GROUPS if g not in CORE_GROUPS and cfg.get(g) is not None}
    extra.update({g: OmegaConf.to_container(cfg[g], resolve=True) for g in SYSTEM_GROUPS
                  if g not in GROUPS and cfg.get(g) is not None})
    loo = OmegaConf.to_container(cfg.get("loo") or {}, resolve=True)
    try:
        loo = LooParams(**loo)
    except TypeError as e:
        raise ConfigError(f"invalid loo config: {e}") from None
    return Params(seed=int(cfg.get("seed", 0)), cache_dir=str(cfg.cache_dir), progress=bool(cfg.get("progress", True)),
                  loo=loo, extra=extra, **core)


def run_task(cfg: DictConfig, out_dir: str | Path) -> dict:
    """Run the task named by ``cfg.task.name`` and write ``summary.json`` into ``out_dir``."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    name = cfg.task.name
    try:
        module = importlib.import_module(f"convsynth_jax.tasks.{name}")
    except ModuleNotFoundError as e:
        if e.name and e.name.endswith(f"tasks.{name}"):
            raise ConfigError(f"unknown task {name!r}") from None
        raise
    from . import kernel_cache

    kernel_cache.enable_compilation_cache(cfg.get("jax_cache"))
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
        write_json_atomic(Path(out_dir) / "summary.json",
                          {"task": cfg.task.name, "success": False, "error": str(e)})
        if os.environ.get("CONVSYNTH_RAISE", "1") != "0":
            raise SystemExit(2) from e
        return None
    log.info("wrote %s", Path(out_dir) / "summary.json")
    return summary


def compose(overrides: list[str] | None = None) -> DictConfig:
    """Compose the primary config without running (for notebooks and tests)."""
    from hydra import compose as _compose, initialize_config_dir

    with initialize_config_dir(version_base="1.3", config_dir=CONFIG_DIR):
        return _compose(config_name="config", overrides=list(overrides or []))


def default_params(overrides: list[str] | None = None):
    """The typed parameters of the shipped config with ``overrides`` (for notebooks, tests and the API)."""
    return to_params(compose(overrides))


if __name__ == "__main__":  # pragma: no cover
    main()
