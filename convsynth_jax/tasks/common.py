"""Helpers shared by tasks: typed parameters, the configured corpus and its cached annotation, the
configured synthesis system."""
from __future__ import annotations

import logging
from pathlib import Path

from ..errors import ConfigError

log = logging.getLogger(__name__)


def enable_compilation_cache(cfg) -> Path | None:
    """:func:`convsynth_jax.kernel_cache.enable_compilation_cache` with the config's ``jax_cache`` group
    (off when the config has none)."""
    from .. import kernel_cache
    from ..config import group_params

    return kernel_cache.enable_compilation_cache(group_params(cfg, "jax_cache") if cfg.get("jax_cache") is not None
                                                 else None)


def params_of(cfg):
    """The typed parameters of a composed config (converted once per task)."""
    from ..config import to_params

    return to_params(cfg)


def open_corpus(params):
    """Open the dyadic corpus named by ``params.corpus`` (generating the synthetic one on first use)."""
    from ..io.corpus import load_corpus

    c = params.corpus
    needed = {"genea": "root", "bvh_folder": "root", "manifest": "path"}.get(c.kind)
    if needed and getattr(c, needed) is None:
        raise ConfigError(f"corpus={c.kind} needs corpus.{needed}=" + ("FILE" if needed == "path" else "DIR"))
    if c.kind == "synthetic":
        from ..data import ensure_synthetic_corpus

        root = ensure_synthetic_corpus({"name": c.name or "synthetic_default", "root": c.root, "generator": c.generator},
                                       cache_dir=params.cache_dir)
        return load_corpus(root, layout="genea", tolerance=c.duration_tolerance, characters=c.characters)
    if c.kind == "genea":
        return load_corpus(c.root, layout="genea", tolerance=c.duration_tolerance, characters=c.characters)
    if c.kind == "manifest":
        return load_corpus(c.path, layout="manifest", tolerance=c.duration_tolerance, characters=c.characters)
    raise ConfigError(f"corpus kind {c.kind!r} is not a dyadic corpus (expected synthetic, genea or manifest)")


def cache_dir(params) -> Path:
    """Where annotations and fitted models are cached (``<cache_dir>/loo_cache``)."""
    return Path(params.cache_dir) / "loo_cache"


def annotated_corpus(params):
    """(corpus, annotations: session -> role -> ParticipantAnnotation), annotations cached on disk."""
    from ..annotate.cache import annotate_corpus_cached

    corpus = open_corpus(params)
    ann = annotate_corpus_cached(corpus, params.annotate, params.fps, cache_dir(params), progress=params.progress)
    return corpus, ann


def make_configured_system(params):
    """The synthesis system selected by ``system=...`` (conf/system/<name>.yaml)."""
    from ..systems.base import make_system

    return make_system(params, params.system)
