"""Exported kernels kept between runs (issue #15, part 3): a second run skips JAX's tracing and lowering.

JAX's persistent compilation cache (``jax_cache.dir``) stores compiled executables, but it is
consulted only after a kernel has been traced to a jaxpr and lowered to StableHLO, which for the
search kernels costs 0.1-0.3 s each in a fresh process. :func:`call` runs a jitted kernel through a
``jax.export`` of it instead: the first time a kernel is called with given argument shapes, dtypes
and static arguments, it is exported (traced and lowered once) and serialized to
``<jax_cache.export_dir>/<name>-<key>.jaxexport``; a later process reads that file and calls the
exported module, whose executable the compilation cache then supplies.

The key hashes the kernel's name, the argument tree, every argument's shape and dtype, the static
arguments, the package version and the source of every module of the package, the JAX and jaxlib
versions, the backend and the JAX settings that change what a kernel computes (64-bit mode, the PRNG
implementation). So a file is never used for other code or other shapes: an edited source file
gives new keys (the old files are simply not read again). A file holds a magic line, the key and a
SHA-256 of its payload; one that does not check out (truncated, corrupt, another key) is ignored
and written anew, never deserialized. The folder holds only these files and is safe to delete.
Writes are atomic (temporary file, then rename). Within a process the loaded kernel is kept per key.
Without an export folder (``jax_cache.dir=null`` or ``jax_cache.export_dir=null``, and in library
use unless :func:`set_export_dir` was called) :func:`call` calls the jitted kernel directly.
"""
from __future__ import annotations

import hashlib
import logging
from pathlib import Path

import jax
import numpy as np

from .utils import atomic_path

log = logging.getLogger(__name__)

MAGIC = b"convsynth-jax-export 1\n"
SUFFIX = ".jaxexport"

_DIR: Path | None = None
_LOADED: dict = {}      # key -> jitted call of the Exported (one per process and key)
_ENV: list = []         # the environment part of the key, computed once per process


def set_export_dir(path: str | Path | None) -> None:
    """Store exported kernels under ``path`` (created when the first one is written); None: off."""
    global _DIR
    _DIR = None if path is None else Path(path)


def export_dir() -> Path | None:
    return _DIR


def _environment() -> str:
    """Package version + source hash, JAX/jaxlib versions, backend, and the settings kernels depend on."""
    if not _ENV:
        import jaxlib

        from . import __version__

        h = hashlib.sha256()
        root = Path(__file__).resolve().parent
        for p in sorted(root.rglob("*.py")):
            h.update(str(p.relative_to(root)).encode() + b"\0" + p.read_bytes() + b"\0")
        _ENV.append(repr((__version__, h.hexdigest(), jax.__version__, jaxlib.__version__, jax.default_backend(),
                          bool(jax.config.jax_enable_x64), str(jax.config.jax_default_prng_impl),
                          bool(jax.config.jax_threefry_partitionable))))
    return _ENV[0]


def _dtype(x):
    d = getattr(x, "dtype", None)
    return np.dtype(d) if d is not None else np.result_type(x)


def kernel_key(name: str, args: tuple, static: dict) -> str:
    """The file key of ``name`` called with ``args`` (a pytree of arrays) and ``static`` arguments."""
    leaves, tree = jax.tree.flatten(args)
    avals = tuple((tuple(np.shape(x)), _dtype(x).str) for x in leaves)
    text = repr((name, str(tree), avals, sorted(static.items()), _environment()))
    return hashlib.sha256(text.encode()).hexdigest()[:40]


def path_of(name: str, key: str) -> Path:
    return _DIR / f"{name}-{key}{SUFFIX}"


def _read(path: Path, key: str):
    """The Exported stored at ``path`` for ``key``, or None when absent or not exactly what was written."""
    from jax import export

    try:
        data = path.read_bytes()
    except FileNotFoundError:
        return None
    except OSError as e:
        log.warning("%s: cannot read the exported kernel (%s); exporting it again", path, e)
        return None
    head = MAGIC + key.encode() + b"\n"
    digest = data[len(head):len(head) + 64]
    payload = data[len(head) + 65:]
    if (not data.startswith(head) or data[len(head) + 64:len(head) + 65] != b"\n"
            or hashlib.sha256(payload).hexdigest().encode() != digest):
        log.warning("%s: not a complete exported kernel for this key (corrupt or truncated); exporting it again", path)
        return None
    try:
        return export.deserialize(bytearray(payload))
    except Exception as e:  # noqa: BLE001 - a checked file of another JAX build: export again
        log.warning("%s: cannot deserialize the exported kernel (%s); exporting it again", path, e)
        return None


def _write(path: Path, key: str, exported) -> None:
    payload = bytes(exported.serialize())
    try:
        with atomic_path(path) as tmp:
            tmp.write_bytes(MAGIC + key.encode() + b"\n" + hashlib.sha256(payload).hexdigest().encode() + b"\n"
                            + payload)
    except OSError as e:
        log.warning("%s: cannot store the exported kernel (%s); the next run exports it again", path, e)


def _compatible(exported, leaves) -> bool:
    avals = [(tuple(a.shape), np.dtype(a.dtype)) for a in exported.in_avals]
    return (avals == [(tuple(np.shape(x)), _dtype(x)) for x in leaves]
            and jax.default_backend() in exported.platforms)


def call(fun, name: str, args: tuple, static: dict | None = None):
    """``fun(*args, **static)`` for a jitted ``fun``, through its stored export when an export folder is set
    (module docstring). ``args``: positional arguments (pytrees of arrays; None allowed); ``static``: the
    static keyword arguments (hashable). The outputs are the same arrays as the jitted call's."""
    static = dict(static or {})
    if _DIR is None:
        return fun(*args, **static)
    from jax import export

    leaves, tree = jax.tree.flatten(args)
    key = kernel_key(name, args, static)
    f = _LOADED.get(key)
    if f is None:
        path = path_of(name, key)
        exported = _read(path, key)
        if exported is not None and not _compatible(exported, leaves):
            log.warning("%s: the exported kernel's inputs do not match this call; exporting it again", path)
            exported = None
        if exported is None:
            def flat(*xs):
                return fun(*jax.tree.unflatten(tree, xs), **static)

            exported = export.export(jax.jit(flat))(*leaves)
            _write(path, key, exported)
        f = jax.jit(exported.call)
        _LOADED[key] = f
    return f(*leaves)
