"""The public entry points for scripts, notebooks and experiments: typed parameters -> the configured
corpus, its cached annotation, the cache folder, the configured synthesis system.

Everything here takes the typed :class:`~convsynth_jax.params.Params` (``config.default_params(...)``
or ``params_of(cfg)``); the tasks (``convsynth task=...``) use the same functions, so a script that
calls them sees what a task sees. Annotations are cached on disk keyed by the corpus's content and
the annotating code (:mod:`convsynth_jax.annotate.cache`). Results of scripts are written with their
manifest by :func:`write_result` / :func:`write_result_markdown` (:mod:`convsynth_jax.manifest`).
"""
from __future__ import annotations

import logging
from pathlib import Path

from .errors import ConfigError
from .manifest import (REPO, RESULTS, SHARED_DATA, ProcessRun, peak_rss_mb, process_memory_mb, reset_peak_rss,
                       results_inventory, run_convsynth, run_manifest, timed, write_result, write_result_manifest,
                       write_result_markdown)

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


def loo_setup(overrides):
    """(params, annotated sessions, system) of the configured corpus and system under ``overrides``
    (Hydra override strings): what a leave-one-out analysis starts from. The annotations come from
    the cache when they are there; the corpus is annotated before the system is made."""
    from .config import default_params

    params = default_params(overrides)
    _, ann = annotated_corpus(params)
    return params, ann, make_configured_system(params)


def autoencoder_training(params, task) -> tuple[list, str]:
    """(Motions the FGD autoencoder of ``task=benchmark`` trains on, where they come from): the synthetic
    generator under another seed for a synthetic corpus, else the corpus folder ``task.autoencoder_corpus``;
    none (the autoencoder FGD is skipped) when neither exists. ``task``: the benchmark's settings."""
    from .data import ensure_synthetic_corpus
    from .io.corpus import load_corpus

    c = params.corpus
    if task.autoencoder_corpus:
        root = Path(task.autoencoder_corpus)
    elif c.kind == "synthetic":
        gen = dict(c.generator)
        seed = int(gen.get("seed", 0)) + task.autoencoder_seed_offset
        gen.update(seed=seed, num_sessions=task.autoencoder_sessions)
        name = f"{c.name or 'synthetic_default'}_autoencoder_seed{seed}_n{task.autoencoder_sessions}"
        root = ensure_synthetic_corpus({"name": name, "root": None, "generator": gen}, cache_dir=params.cache_dir)
    else:
        log.warning("no corpus for the FGD autoencoder (task.autoencoder_corpus): the autoencoder FGD is skipped")
        return [], "none"
    corpus = load_corpus(root, layout="genea", tolerance=c.duration_tolerance)
    motions = [p.load_motion(params.fps) for s in corpus.sessions for p in s.participants]
    return motions, str(root)


def cdbn_params(cfg):
    """The constrained DBN's typed parameters (``cdbn.*``) of a composed config."""
    from .config import group_params

    return group_params(cfg, "cdbn")


def cdbn_corpus_root(cfg, p) -> Path:
    """Where the CDBN's semi-synthetic corpus lives: ``cdbn.corpus_root``, else under the cache folder."""
    return Path(p.corpus_root) if p.corpus_root else Path(cfg.cache_dir) / "cdbn_semisynthetic"


def cdbn_semisynthetic_params(p):
    """``cdbn.data`` at the model's frame rate (``cdbn.features.fps``)."""
    import dataclasses

    return dataclasses.replace(p.data, fps=p.features.fps)


def cdbn_corpus(cfg, p) -> Path:
    """The CDBN's semi-synthetic corpus folder, generated on first use."""
    from .cdbn.semisynthetic import ensure_corpus

    return ensure_corpus(cdbn_corpus_root(cfg, p), cdbn_semisynthetic_params(p))


__all__ = ["REPO", "RESULTS", "SHARED_DATA", "ProcessRun", "annotated_corpus", "autoencoder_training", "cache_dir",
           "cdbn_corpus", "cdbn_corpus_root", "cdbn_params", "cdbn_semisynthetic_params", "loo_setup",
           "make_configured_system", "open_corpus", "pairing_note", "params_of", "peak_rss_mb", "process_memory_mb",
           "reset_peak_rss", "results_inventory", "run_convsynth", "run_manifest", "timed", "write_result",
           "write_result_manifest", "write_result_markdown"]
