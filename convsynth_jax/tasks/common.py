"""Helpers shared by tasks: opening the configured corpus, seeding, progress bars."""
from __future__ import annotations

import logging
from pathlib import Path

from ..errors import ConfigError

log = logging.getLogger(__name__)


def open_corpus(cfg):
    """Open the corpus named by ``cfg.corpus`` (generating the synthetic one on first use)."""
    kind = cfg.corpus.kind
    from ..io.corpus import load_corpus

    if kind == "synthetic":
        from ..data import ensure_synthetic_corpus

        root = ensure_synthetic_corpus(cfg.corpus, cache_dir=cfg.cache_dir)
        return load_corpus(root, layout="genea", tolerance=cfg.corpus.get("duration_tolerance", 1.0))
    if kind == "genea":
        return load_corpus(cfg.corpus.root, layout="genea", tolerance=cfg.corpus.get("duration_tolerance", 1.0))
    if kind == "manifest":
        return load_corpus(cfg.corpus.path, layout="manifest", tolerance=cfg.corpus.get("duration_tolerance", 1.0))
    raise ConfigError(f"corpus kind {kind!r} is not a dyadic corpus (expected synthetic, genea or manifest)")
