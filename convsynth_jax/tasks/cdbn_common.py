"""Shared wiring of the cdbn_* tasks: config -> parameters, the semi-synthetic corpus location."""
from __future__ import annotations

from pathlib import Path

from ..cdbn.params import CDBNParams, cdbn_params_from_config


def params(cfg) -> CDBNParams:
    return cdbn_params_from_config(cfg.cdbn)


def corpus_root(cfg, p: CDBNParams) -> Path:
    root = p.extra.get("corpus_root")
    return Path(root) if root else Path(cfg.cache_dir) / "cdbn_semisynthetic"


def ensure_corpus(cfg, p: CDBNParams) -> Path:
    from ..cdbn.semisynthetic import ensure_corpus as _ensure
    from ..cdbn.semisynthetic import params_from_dict

    dp = params_from_dict({**(p.extra.get("data") or {}), "fps": p.features.fps})
    return _ensure(corpus_root(cfg, p), dp)
