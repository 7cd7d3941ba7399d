"""Hydra entry point of the ``convsynth`` command. The only library module that imports hydra.

``convsynth task=NAME ...`` composes ``conf/config.yaml``, then calls
``convsynth_jax.tasks.NAME.run(cfg, out_dir)``, which returns a summary dict; the summary is written
as ``summary.json`` into Hydra's output directory (``conf/hydra/`` decides where that is).
"""
from __future__ import annotations

import importlib
import logging
import os
import time
from pathlib import Path

import hydra
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig, OmegaConf

from .errors import ConfigError, ConvSynthError
from .utils import write_json_atomic

log = logging.getLogger("convsynth_jax")

# conf/ lives at the top of the repository (design card); an editable install finds it here.
CONFIG_DIR = str(Path(__file__).resolve().parent.parent / "conf")


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


if __name__ == "__main__":  # pragma: no cover
    main()
