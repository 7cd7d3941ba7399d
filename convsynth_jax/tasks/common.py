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
    needed = {"genea": "root", "bvh_folder": "root", "manifest": "path", "beat2": "root"}.get(c.kind)
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
    if c.kind == "beat2":
        from ..io.beat2 import load_beat2

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
    from ..annotate.cache import annotate_corpus_cached

    corpus = open_corpus(params)
    ann = annotate_corpus_cached(corpus, params.annotate, params.fps, cache_dir(params), progress=params.progress)
    return corpus, ann


def make_configured_system(params):
    """The synthesis system selected by ``system=...`` (conf/system/<name>.yaml)."""
    from ..systems.base import make_system

    return make_system(params, params.system)


def graph_file_models(given, ann, system):
    """Motion-graph models from graph files (``task.graphs.<character>=FILE``: task=synthesize and
    task=converse), each clip checked against the configured corpus's recordings."""
    from ..graph import load_graph
    from ..systems.motion_graph import MotionGraphSystem

    if not isinstance(system, MotionGraphSystem):
        raise ConfigError(f"task.graphs gives motion graphs: it needs system=motion_graph (got {system.name!r})")
    out = {}
    for char, path in given.items():
        g = load_graph(path)
        motions, labels = {}, {}
        for cn in g.clip_names:
            s_name, role = cn.rsplit("_", 1)
            if s_name not in ann or role not in ann[s_name]:
                raise ConfigError(f"graph {path}: clip {cn!r} is not a recording of the configured corpus")
            a = ann[s_name][role]
            motions[cn], labels[cn] = a.motion, (a.own, a.partner)
        out[char] = system.graph_model(g, motions, 0.0, labels)   # with the configured penalties
    system.prepare(out)
    return out
