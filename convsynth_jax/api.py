"""The public entry points for scripts, notebooks and experiments: typed parameters -> the configured
corpus, its cached annotation, the cache folder, the configured synthesis system.

Everything here takes the typed :class:`~convsynth_jax.params.Params` (``config.default_params(...)``
or ``params_of(cfg)``); the tasks (``convsynth task=...``) use the same functions, so a script that
calls them sees what a task sees. Annotations are cached on disk keyed by the corpus's content and
the annotating code (:mod:`convsynth_jax.annotate.cache`).
"""
from __future__ import annotations

import logging
from pathlib import Path

from .errors import ConfigError

log = logging.getLogger(__name__)


def params_of(cfg):
    """The typed parameters of a composed config (converted once per task)."""
    from .config import to_params

    return to_params(cfg)


def open_corpus(params):
    """Open the dyadic corpus named by ``params.corpus`` (generating the synthetic one on first use)."""
    from .io.corpus import load_corpus

    c = params.corpus
    needed = {"genea": "root", "bvh_folder": "root", "manifest": "path", "beat2": "root"}.get(c.kind)
    if needed and getattr(c, needed) is None:
        raise ConfigError(f"corpus={c.kind} needs corpus.{needed}=" + ("FILE" if needed == "path" else "DIR"))
    if c.kind == "synthetic":
        from .data import ensure_synthetic_corpus

        root = ensure_synthetic_corpus({"name": c.name or "synthetic_default", "root": c.root, "generator": c.generator},
                                       cache_dir=params.cache_dir)
        return load_corpus(root, layout="genea", tolerance=c.duration_tolerance, characters=c.characters)
    if c.kind == "genea":
        return load_corpus(c.root, layout="genea", tolerance=c.duration_tolerance, characters=c.characters)
    if c.kind == "manifest":
        return load_corpus(c.path, layout="manifest", tolerance=c.duration_tolerance, characters=c.characters)
    if c.kind == "beat2":
        from .io.beat2 import load_beat2

        return load_beat2(c.root, c.pairing, c.pseudo_shift_s, c.smplx_model, c.characters,
                          derived_dir=Path(params.cache_dir) / "beat2_pseudo_dyads", tolerance=c.duration_tolerance)
    raise ConfigError(f"corpus kind {c.kind!r} is not a dyadic corpus (expected synthetic, genea, manifest or beat2)")


def pairing_note(corpus) -> dict:
    """``{"pairing": ..., "partner_statistics": "null control", ...}`` for a corpus of pseudo-dyads
    (its partner statistics are a null control, and task outputs say so); {} for a real dyadic corpus."""
    meta = getattr(corpus, "metadata", {}) or {}
    if meta.get("pairing") != "pseudo_dyad":
        return {}
    return {"pairing": "pseudo_dyad", "partner_statistics": "null control", "pairing_note": meta.get("note", "")}


def cache_dir(params) -> Path:
    """Where annotations and fitted models are cached (``<cache_dir>/loo_cache``)."""
    return Path(params.cache_dir) / "loo_cache"


def annotated_corpus(params):
    """(corpus, annotations: session -> role -> ParticipantAnnotation), annotations cached on disk."""
    from .annotate.cache import annotate_corpus_cached

    corpus = open_corpus(params)
    ann = annotate_corpus_cached(corpus, params.annotate, params.fps, cache_dir(params), progress=params.progress)
    return corpus, ann


def make_configured_system(params):
    """The synthesis system selected by ``system=...`` (conf/system/<name>.yaml)."""
    from .systems.base import make_system

    return make_system(params, params.system)


__all__ = ["annotated_corpus", "cache_dir", "make_configured_system", "open_corpus", "pairing_note", "params_of"]
