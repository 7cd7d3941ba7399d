"""Shared wiring of the cdbn_* tasks: config -> parameters, the semi-synthetic corpus location."""
from __future__ import annotations

import dataclasses
from pathlib import Path

from ..cdbn.params import CDBNParams


def params(cfg) -> CDBNParams:
    from ..config import group_params

    return group_params(cfg, "cdbn")


def corpus_root(cfg, p: CDBNParams) -> Path:
    root = p.corpus_root
    return Path(root) if root else Path(cfg.cache_dir) / "cdbn_semisynthetic"


def semisynthetic_params(p: CDBNParams):
    """``cdbn.data`` at the model's frame rate (``cdbn.features.fps``)."""
    return dataclasses.replace(p.data, fps=p.features.fps)


def ensure_corpus(cfg, p: CDBNParams) -> Path:
    from ..cdbn.semisynthetic import ensure_corpus as _ensure

    return _ensure(corpus_root(cfg, p), semisynthetic_params(p))
