"""Task ``cdbn_make_data``: the semi-synthetic nod/shake corpus (``convsynth_jax.cdbn.semisynthetic``)
in ``cdbn.corpus_root`` (default ``<cache_dir>/cdbn_semisynthetic``)."""
from __future__ import annotations

from pathlib import Path

from .cdbn_common import corpus_root, params


def run(cfg, out_dir: Path) -> dict:
    from ..cdbn.semisynthetic import make_semisynthetic_corpus, params_from_dict

    p = params(cfg)
    dp = params_from_dict({**(p.extra.get("data") or {}), "fps": p.features.fps})
    root = corpus_root(cfg, p)
    stats = make_semisynthetic_corpus(root, dp)
    return {"success": True, "corpus_root": str(root), **stats}
