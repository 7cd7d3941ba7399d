"""Task ``make_corpus``: write the synthetic corpus (``corpus=synthetic`` or ``corpus=synthetic_tiny``)
into ``corpus.root`` or ``${cache_dir}/<name>``; ``task.force=true`` regenerates it."""
from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from ..data import ensure_synthetic_corpus, make_synthetic_corpus
from ..errors import ConfigError


@dataclass(frozen=True)
class MakeCorpusSettings:
    """``conf/task/make_corpus.yaml``."""

    name: str = "make_corpus"
    force: bool = False                 # write the corpus again even when the cached one matches


def run(cfg, out_dir: Path) -> dict:
    from ..config import task_settings
    from .common import params_of

    params = params_of(cfg)
    c = params.corpus
    if c.kind != "synthetic":
        raise ConfigError(f"make_corpus needs a synthetic corpus config, got kind={c.kind!r}")
    t0 = time.perf_counter()
    name = c.name or "synthetic_default"
    if task_settings(cfg).force:
        root = Path(c.root) if c.root else Path(params.cache_dir) / name
        root = make_synthetic_corpus(root, c.generator)
    else:
        root = ensure_synthetic_corpus({"name": name, "root": c.root, "generator": c.generator}, params.cache_dir)
    seconds = time.perf_counter() - t0
    meta = json.loads((root / "corpus.json").read_text())
    events = pd.read_csv(root / "events.csv")
    counts = events.groupby(["participant", "kind"]).size().unstack(fill_value=0)
    return {"corpus_root": str(root), "num_sessions": len(meta["sessions"]),
            "total_seconds": sum(s["duration"] for s in meta["sessions"]),
            "characters": meta["characters"], "event_counts": counts.to_dict(orient="index"),
            "seconds": seconds}
