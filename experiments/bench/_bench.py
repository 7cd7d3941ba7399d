"""Helpers for the benchmark and analysis scripts: timing, peak memory, result files with a manifest.

Every result written here (``experiments/results/<name>.json`` or ``.md``) gets
``experiments/results/<name>.manifest.json``: command, overrides, commit, date and machine load
(``convsynth_jax.manifest.run_manifest``)."""
import json
import resource
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))
RESULTS = REPO / "experiments" / "results"
SHARED = REPO.parent / "shared" / "data"

from convsynth_jax.manifest import run_manifest  # noqa: E402


def peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def timed(fn, *a, **k):
    t = time.perf_counter()
    out = fn(*a, **k)
    return out, time.perf_counter() - t


def write_manifest(name: str, overrides=None, **extra) -> Path:
    """experiments/results/<name>.manifest.json (or <name>/manifest.json when <name> is a folder)."""
    RESULTS.mkdir(parents=True, exist_ok=True)
    target = RESULTS / name
    path = target / "manifest.json" if target.is_dir() else RESULTS / f"{name}.manifest.json"
    path.write_text(json.dumps(run_manifest(overrides=overrides, **extra), indent=2) + "\n")
    return path


def write(name: str, result: dict, overrides=None) -> None:
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / f"{name}.json").write_text(json.dumps(result, indent=2, default=float))
    write_manifest(name, overrides=overrides)
    print(json.dumps(result, indent=2, default=float))


def write_markdown(name: str, lines: list, overrides=None) -> None:
    """experiments/results/<name>.md from the lines of a Markdown table, and print them."""
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / f"{name}.md").write_text("\n".join(lines) + "\n")
    write_manifest(name, overrides=overrides)
    print("\n".join(lines))


def loo_setup(overrides):
    """(params, annotated sessions, system) of the configured corpus and system under ``overrides``
    (Hydra override strings): what a leave-one-out analysis starts from. The annotations come from
    the cache when they are there; the corpus is annotated before the system is made."""
    from convsynth_jax.config import default_params
    from convsynth_jax.systems.base import make_system
    from convsynth_jax.api import annotated_corpus

    params = default_params(overrides)
    _, ann = annotated_corpus(params)
    return params, ann, make_system(params, params.system)
