"""Where the notebooks find their inputs: a finished `convsynth` main run (env CONVSYNTH_NB_RESULTS,
default: the newest outputs/main/*) and the corpus it used (env CONVSYNTH_NB_CORPUS, default: read
from the run's summary)."""
import json
import os
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent if "__file__" in globals() else Path.cwd().parent


def results_dir() -> Path:
    env = os.environ.get("CONVSYNTH_NB_RESULTS")
    if env:
        return Path(env)
    runs = sorted((REPO / "outputs" / "main").glob("*/summary.json"))
    if not runs:
        raise FileNotFoundError("no finished main run: run `convsynth` first or set CONVSYNTH_NB_RESULTS")
    return runs[-1].parent


def corpus_dir() -> Path:
    env = os.environ.get("CONVSYNTH_NB_CORPUS")
    if env:
        return Path(env)
    summary = json.loads((results_dir() / "summary.json").read_text())
    return Path(summary["corpus_root"])
