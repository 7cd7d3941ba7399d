"""Annotations of a whole corpus, cached on disk keyed by the corpus folder, the content of its files
(:func:`convsynth_jax.io.corpus.corpus_fingerprint`), the parameters that shape them and the code that
computes them (:func:`convsynth_jax.fingerprint.code_fingerprint` of io and annotate), so that every
task (Table 1, leave-one-out folds, synthesis, the main job) reuses them, and a file edited in place or
an edited annotator computes them again."""
from __future__ import annotations

import logging
import pickle
from pathlib import Path

from ..fingerprint import code_fingerprint, stable_hash
from ..io.corpus import corpus_fingerprint
from ..utils import atomic_path, file_lock
from .params import AnnotateParams
from .pipeline import annotate_corpus

log = logging.getLogger(__name__)


ANNOTATION_CODE = ("io", "annotate")   # the subpackages an annotation depends on (above the foundation)


def annotation_key(corpus, params: AnnotateParams, fps: float) -> str:
    """The cache key of ``corpus``'s annotation: its folder (annotations name their audio files), its
    content, the parameters, the frame rate and the annotating code."""
    # the character names are part of the annotation (corpus.characters may rename them)
    names = [(s.name, p.role, p.character) for s in corpus.sessions for p in s.participants]
    return stable_hash(str(Path(corpus.root).resolve()), corpus_fingerprint(corpus), params, float(fps), names,
                       code_fingerprint(*ANNOTATION_CODE))


def annotate_corpus_cached(corpus, params: AnnotateParams, fps: float, cache_dir: str | Path | None = None,
                           progress: bool = True, workers: int | None = None) -> dict:
    """session name -> role -> ParticipantAnnotation for ``corpus``, read from ``cache_dir`` when an
    annotation with the same corpus folder (and contents), parameters and frame rate is there, else computed and
    written there (atomically). The key also holds the content of the corpus's files and the annotating
    code's fingerprint, so an edited file or annotator is annotated again. An unreadable cache file is
    ignored and rebuilt."""
    key = annotation_key(corpus, params, fps)
    cache = Path(cache_dir) / f"annotations_{key}.pkl" if cache_dir else None
    if cache is None:
        return annotate_corpus(corpus, params, fps, progress=progress, workers=workers)
    found = _read_cached(cache)
    if found is not None:
        return found
    # several processes on one cache folder: the first computes, the others wait and read its file
    with file_lock(cache):
        found = _read_cached(cache)
        if found is not None:
            return found
        result = annotate_corpus(corpus, params, fps, progress=progress, workers=workers)
        with atomic_path(cache, suffix=".pkl") as tmp:
            with open(tmp, "wb") as fh:
                pickle.dump(result, fh, protocol=pickle.HIGHEST_PROTOCOL)
    return result


def _read_cached(cache: Path) -> dict | None:
    """The annotation stored in ``cache``, or None when absent or unreadable (rebuilt, never trusted)."""
    if not cache.is_file():
        return None
    try:
        with open(cache, "rb") as fh:
            return pickle.load(fh)
    except Exception as e:  # a stale or foreign cache is rebuilt, never trusted
        log.warning("ignoring unreadable annotation cache %s (%s)", cache, e)
        return None
