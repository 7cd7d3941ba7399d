"""Annotations of a corpus, cached on disk one file per session, keyed by the corpus folder, the content
of the session's files (:func:`convsynth_jax.io.corpus.participant_fingerprint`), the parameters that
shape them and the code that computes them (:func:`convsynth_jax.fingerprint.code_fingerprint` of io and
annotate), so that every task (Table 1, leave-one-out folds, synthesis, the main job) reuses them, and a
file edited in place (or an edited annotator) re-annotates what depends on it and nothing else."""
from __future__ import annotations

import dataclasses
import logging
import pickle
from pathlib import Path

from ..fingerprint import code_fingerprint, stable_hash
from ..io.corpus import corpus_fingerprint, participant_fingerprint
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


def session_key(corpus, session, params: AnnotateParams, fps: float) -> str:
    """The cache key of one session's annotation: the corpus folder (annotations name their audio
    files), the session's name and its participants' content (:func:`participant_fingerprint`: roles,
    characters and file bytes), the parameters, the frame rate and the annotating code. A session is
    annotated from its own files only, so an edit of one file re-annotates its session alone."""
    root = Path(corpus.root)
    return stable_hash(str(root.resolve()), session.name, [participant_fingerprint(p, root) for p in session.participants],
                       params, float(fps), code_fingerprint(*ANNOTATION_CODE))


def annotate_corpus_cached(corpus, params: AnnotateParams, fps: float, cache_dir: str | Path | None = None,
                           progress: bool = True, workers: int | None = None) -> dict:
    """session name -> role -> ParticipantAnnotation for ``corpus``: each session read from
    ``cache_dir`` (``annotations_<session_key>.pkl``) when its annotation with the same content,
    parameters, frame rate and code is there, else computed and written there (atomically); the
    sessions of an edited file are annotated again, the others are read. An unreadable cache file is
    ignored and rebuilt."""
    if not cache_dir:
        return annotate_corpus(corpus, params, fps, progress=progress, workers=workers)
    sessions = list(corpus.sessions)
    paths = {s.name: Path(cache_dir) / f"annotations_{session_key(corpus, s, params, fps)}.pkl" for s in sessions}
    found = {n: _read_cached(p) for n, p in paths.items()}
    if any(a is None for a in found.values()):
        # several processes on one cache folder: the first computes, the others wait and read its files
        with file_lock(Path(cache_dir) / f"annotations_{annotation_key(corpus, params, fps)}.pkl"):
            found = {n: a if a is not None else _read_cached(paths[n]) for n, a in found.items()}
            missing = [s for s in sessions if found[s.name] is None]
            if missing:
                done = annotate_corpus(dataclasses.replace(corpus, sessions=missing) if dataclasses.is_dataclass(corpus)
                                       else _Sessions(missing), params, fps, progress=progress, workers=workers)
                for s in missing:
                    with atomic_path(paths[s.name], suffix=".pkl") as tmp:
                        with open(tmp, "wb") as fh:
                            pickle.dump(done[s.name], fh, protocol=pickle.HIGHEST_PROTOCOL)
                    found[s.name] = done[s.name]
    return {s.name: found[s.name] for s in sessions}


class _Sessions:
    """A corpus-like object holding only ``sessions`` (what annotate_corpus reads)."""

    def __init__(self, sessions):
        self.sessions = sessions


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
