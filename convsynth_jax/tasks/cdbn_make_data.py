"""Task ``cdbn_make_data``: the semi-synthetic nod/shake corpus (``convsynth_jax.cdbn.semisynthetic``)
in ``cdbn.corpus_root`` (default ``<cache_dir>/cdbn_semisynthetic``)."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..api import cdbn_corpus_root as corpus_root, cdbn_params as params, cdbn_semisynthetic_params as semisynthetic_params


@dataclass(frozen=True)
class CDBNMakeDataSettings:
    """``conf/task/cdbn_make_data.yaml`` (the corpus's settings are the cdbn group's ``data``)."""

    name: str = "cdbn_make_data"


def run(cfg, out_dir: Path) -> dict:
    from ..cdbn.semisynthetic import make_semisynthetic_corpus

    p = params(cfg)
    dp = semisynthetic_params(p)
    root = corpus_root(cfg, p)
    stats = make_semisynthetic_corpus(root, dp)
    return {"success": True, "corpus_root": str(root), **stats}
