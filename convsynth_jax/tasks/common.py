"""Helpers shared by tasks: typed parameters, the configured corpus and its cached annotation, the
configured synthesis system."""
from __future__ import annotations

import logging
from pathlib import Path

from ..errors import ConfigError

log = logging.getLogger(__name__)


def enable_compilation_cache(cfg) -> Path | None:
    """Turn on JAX's persistent compilation cache at ``cfg.jax_cache.dir`` (default
    ``${cache_dir}/jax_cache``), so a second run of any task loads its compiled kernels from disk
    instead of compiling them again. ``jax_cache.dir=null`` turns it off. The directory holds only
    compiled executables and is safe to delete (the next run recompiles). Entries are written for
    kernels that took at least ``jax_cache.min_compile_time_s`` to compile (default 0: every kernel,
    since on CPU many small ones add up) and are at least ``jax_cache.min_entry_size_bytes`` large.
    The search kernels' executables are also stored whole in ``jax_cache.kernel_dir`` (default
    ``${cache_dir}/jax_kernels``; :mod:`convsynth_jax.kernel_cache`), so a second run skips their
    tracing and lowering too; null turns that off, and so does ``jax_cache.dir=null``.
    Returns the directory (or None when disabled)."""
    import jax

    from .. import kernel_cache

    node = cfg.get("jax_cache") if hasattr(cfg, "get") else None
    path = node.get("dir") if node is not None else None
    if not path:
        _set_cache_dir(jax, None)  # off, also when an earlier task of this process turned it on
        kernel_cache.set_kernel_dir(None)
        return None
    path = Path(str(path)).expanduser().resolve()
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise ConfigError(f"jax_cache.dir={path}: cannot create the compilation cache directory ({e})") from None
    jax.config.update("jax_persistent_cache_min_compile_time_secs", float(node.get("min_compile_time_s", 0.0)))
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", int(node.get("min_entry_size_bytes", 0)))
    _set_cache_dir(jax, str(path))
    kdir = node.get("kernel_dir")
    kernel_cache.set_kernel_dir(Path(str(kdir)).expanduser().resolve() if kdir else None)
    log.debug("jax compilation cache: %s", path)
    return path


def _set_cache_dir(jax, path: str | None) -> None:
    if jax.config.jax_compilation_cache_dir == path:
        return
    jax.config.update("jax_compilation_cache_dir", path)
    try:  # a process that already compiled with another (or no) directory: re-read the setting
        from jax._src import compilation_cache

        if compilation_cache._cache_checked or compilation_cache._cache_initialized:
            compilation_cache.reset_cache()
    except (ImportError, AttributeError):  # pragma: no cover - private API moved
        log.debug("jax compilation cache: reset_cache unavailable")


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
        return load_corpus(root, layout="genea", tolerance=c.duration_tolerance)
    if c.kind == "genea":
        return load_corpus(c.root, layout="genea", tolerance=c.duration_tolerance)
    if c.kind == "manifest":
        return load_corpus(c.path, layout="manifest", tolerance=c.duration_tolerance)
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
