"""Annotations of a whole corpus, cached on disk keyed by the corpus folder and the parameters that
shape them, so that every task (Table 1, leave-one-out folds, synthesis, the main job) reuses them."""
from __future__ import annotations

import dataclasses
import hashlib
import json
import logging
import pickle
from pathlib import Path

from ..utils import atomic_path
from .params import AnnotateParams
from .pipeline import annotate_corpus

log = logging.getLogger(__name__)


def params_hash(*parts) -> str:
    """A short stable hash of dataclasses, dicts, lists and scalars (for cache file names)."""
    def plain(x):
        return dataclasses.asdict(x) if dataclasses.is_dataclass(x) else x

    text = json.dumps([plain(p) for p in parts], sort_keys=True, default=str)
    return hashlib.sha1(text.encode()).hexdigest()[:12]


def annotate_corpus_cached(corpus, params: AnnotateParams, fps: float, cache_dir: str | Path | None = None,
                           progress: bool = True) -> dict:
    """session name -> role -> ParticipantAnnotation for ``corpus``, read from ``cache_dir`` when an
    annotation with the same corpus folder, parameters and frame rate is there, else computed and
    written there (atomically). An unreadable cache file is ignored and rebuilt."""
    key = params_hash(str(Path(corpus.root).resolve()), params, float(fps))
    cache = Path(cache_dir) / f"annotations_{key}.pkl" if cache_dir else None
    if cache is not None and cache.is_file():
        try:
            with open(cache, "rb") as fh:
                return pickle.load(fh)
        except Exception as e:  # a stale or foreign cache is rebuilt, never trusted
            log.warning("ignoring unreadable annotation cache %s (%s)", cache, e)
    result = annotate_corpus(corpus, params, fps, progress=progress)
    if cache is not None:
        with atomic_path(cache, suffix=".pkl") as tmp:
            with open(tmp, "wb") as fh:
                pickle.dump(result, fh, protocol=pickle.HIGHEST_PROTOCOL)
    return result
