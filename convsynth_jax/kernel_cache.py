"""Compiled kernels kept between runs: a second run skips JAX's tracing and
lowering, not only the compilation. Used for the search kernels and the graph construction's.

JAX's persistent compilation cache (``jax_cache.dir``) stores compiled executables, but it is
consulted only after a kernel has been traced to a jaxpr and lowered to StableHLO, which for the
search kernels costs 0.1-0.3 s each in a fresh process. :func:`call` runs a jitted kernel through its
compiled executable stored by ``jax.experimental.serialize_executable`` instead: the first time a
kernel is called with given argument shapes, dtypes and static arguments it is lowered and compiled
(afresh: see :func:`_fresh_compilation`) and the executable is written to
``<jax_cache.kernel_dir>/<name>-<key>.jaxexe``; a later process loads that file and calls it.

The key hashes the kernel's name, the argument tree, every argument's shape and dtype, the static
arguments, the package version and the source of every module in the kernel's folder (for the
search kernels ``convsynth_jax/search/``, where their helpers live; for the construction's
``convsynth_jax/graph/`` or ``convsynth_jax/``) and of this module, the JAX and jaxlib
versions, the backend, the machine and its CPU feature flags, and the JAX settings that change what a
kernel computes (64-bit mode, the PRNG implementation), and ``XLA_FLAGS`` (code generation, forced
device count). So a file is never used for other code, other shapes, other XLA flags or another
machine: an edited source file gives new keys (the old files are simply not read again). A file
holds a magic line, the key and a SHA-256 of its payload; one that does not check out (truncated,
corrupt, another key) is ignored and written anew, never loaded. Like JAX's cache the
folder holds executable code: keep it where only you can write. It is safe to delete. Writes are
atomic (temporary file, then rename). Within a process the loaded kernel is kept per key; loading
and compiling are serialized by a lock (the construction calls its tile kernel from several threads).
:func:`compiled` returns the kernel as a function, for a loop that calls it many times with the same
shapes (no key per call). Without a
folder (``jax_cache.dir=null`` or ``jax_cache.kernel_dir=null``, and in library use unless
:func:`set_kernel_dir` was called) :func:`call` calls the jitted kernel directly.
"""
from __future__ import annotations

import contextlib
import hashlib
import logging
import os
import pickle
import sys
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import jax
import numpy as np

from .errors import ConfigError
from .utils import atomic_path, file_lock

log = logging.getLogger(__name__)

MAGIC = b"convsynth-jax-executable 1\n"
SUFFIX = ".jaxexe"

_DIR: Path | None = None
_LOADED: dict = {}      # key -> the loaded compiled kernel (one per process and key)
_ENV: dict = {}         # kernel folder -> the environment part of the key (once per process)
_LOCK = threading.RLock()


def set_kernel_dir(path: str | Path | None) -> None:
    """Store compiled kernels under ``path`` (created when the first one is written); None: off."""
    global _DIR
    _DIR = None if path is None else Path(path)


def kernel_dir() -> Path | None:
    return _DIR


def _cpu_flags() -> str:
    """The machine and its CPU feature flags (an executable compiled for one CPU may not run on another)."""
    import platform

    try:
        with open("/proc/cpuinfo") as f:
            flags = next((line for line in f if line.startswith(("flags", "Features"))), "")
    except OSError:
        flags = platform.processor()
    return platform.machine() + " " + hashlib.sha256(flags.encode()).hexdigest()


def _environment(fun) -> str:
    """The source of the kernel's package folder (every ``.py`` beside the module that defines ``fun``,
    where a kernel's helpers live) and of this module, the package version, JAX/jaxlib versions,
    backend, machine, the settings kernels depend on, and ``XLA_FLAGS`` (XLA's code generation and
    device count: an executable compiled under other flags is not this process's)."""
    mod = sys.modules.get(getattr(fun, "__module__", None) or "")
    folder = Path(mod.__file__).resolve().parent if getattr(mod, "__file__", None) else None
    if folder not in _ENV:
        import jaxlib

        from . import __version__

        h = hashlib.sha256()
        files = sorted(folder.glob("*.py")) if folder is not None else []
        for p in [*files, Path(__file__).resolve()]:
            h.update(p.name.encode() + b"\0" + p.read_bytes() + b"\0")
        _ENV[folder] = repr((__version__, h.hexdigest(), jax.__version__, jaxlib.__version__, jax.default_backend(),
                             _cpu_flags(), bool(jax.config.jax_enable_x64), str(jax.config.jax_default_prng_impl),
                             bool(jax.config.jax_threefry_partitionable), os.environ.get("XLA_FLAGS", "")))
    return _ENV[folder]


def _dtype(x):
    d = getattr(x, "dtype", None)
    return np.dtype(d) if d is not None else np.result_type(x)


def kernel_key(fun, name: str, args: tuple, static: dict) -> str:
    """The file key of kernel ``fun`` named ``name`` called with ``args`` (a pytree of arrays) and
    ``static`` arguments."""
    leaves, tree = jax.tree.flatten(args)
    avals = tuple((tuple(np.shape(x)), _dtype(x).str) for x in leaves)
    text = repr((name, str(tree), avals, sorted(static.items()), _environment(fun)))
    return hashlib.sha256(text.encode()).hexdigest()[:40]


def path_of(name: str, key: str) -> Path:
    return _DIR / f"{name}-{key}{SUFFIX}"


def _read(path: Path, key: str):
    """The compiled kernel stored at ``path`` for ``key``, or None when absent or not exactly what was
    written."""
    from jax.experimental import serialize_executable

    try:
        data = path.read_bytes()
    except FileNotFoundError:
        return None
    except OSError as e:
        log.warning("%s: cannot read the stored kernel (%s); compiling it again", path, e)
        return None
    head = MAGIC + key.encode() + b"\n"
    digest = data[len(head):len(head) + 64]
    payload = data[len(head) + 65:]
    if (not data.startswith(head) or data[len(head) + 64:len(head) + 65] != b"\n"
            or hashlib.sha256(payload).hexdigest().encode() != digest):
        log.warning("%s: not a complete stored kernel for this key (corrupt or truncated); compiling it again", path)
        return None
    try:
        return serialize_executable.deserialize_and_load(*pickle.loads(payload))
    except Exception as e:  # noqa: BLE001 - a checked file that this JAX cannot load: compile again
        log.warning("%s: cannot load the stored kernel (%s); compiling it again", path, e)
        return None


def _write(path: Path, key: str, compiled) -> None:
    from jax.experimental import serialize_executable

    try:
        payload = pickle.dumps(serialize_executable.serialize(compiled))
    except Exception as e:  # noqa: BLE001 - a backend that cannot serialize: run without storing
        log.warning("%s: cannot serialize the compiled kernel (%s); not stored", path, e)
        return
    try:
        with atomic_path(path) as tmp:
            tmp.write_bytes(MAGIC + key.encode() + b"\n" + hashlib.sha256(payload).hexdigest().encode() + b"\n"
                            + payload)
    except OSError as e:
        log.warning("%s: cannot store the compiled kernel (%s); the next run compiles it again", path, e)


def call(fun, name: str, args: tuple, static: dict | None = None):
    """``fun(*args, **static)`` for a jitted ``fun``, through its stored executable when a folder is set
    (module docstring). ``args``: positional arguments (pytrees of arrays; None allowed); ``static``: the
    static keyword arguments (hashable). The outputs are the same arrays as the jitted call's."""
    static = dict(static or {})
    if _DIR is None:
        return fun(*args, **static)
    leaves = jax.tree.leaves(args)
    f = _LOADED.get(kernel_key(fun, name, args, static))
    if f is not None:
        return f(*leaves)
    f, out = _load_or_compile(fun, name, args, static)
    return out if out is not None else f(*leaves)


def compiled(fun, name: str, args: tuple, static: dict | None = None):
    """A function ``g(*args2)`` equal to ``fun(*args2, **static)`` for arguments ``args2`` of the same
    tree, shapes and dtypes as ``args`` (example arguments, run once when a stored file is loaded, to
    check that it runs), through the stored executable
    when a folder is set: the key is computed once, not per call. Without a folder: the jitted
    ``fun`` with ``static`` bound."""
    static = dict(static or {})
    if _DIR is None:
        return lambda *a: fun(*a, **static)
    f = _LOADED.get(kernel_key(fun, name, args, static))
    if f is None:
        f, _ = _load_or_compile(fun, name, args, static, run=False)
    return lambda *a: f(*jax.tree.leaves(a))


def _load_or_compile(fun, name, args, static, run: bool = True):
    """(the loaded or freshly compiled kernel taking the flat leaves, its outputs on ``args`` or None
    when ``run`` is false or it was compiled), stored under its key; one thread at a time."""
    leaves, tree = jax.tree.flatten(args)
    key = kernel_key(fun, name, args, static)
    with _LOCK:
        f = _LOADED.get(key)
        if f is not None:
            return f, None
        path = path_of(name, key)

        def flat(*xs):
            return fun(*jax.tree.unflatten(tree, xs), **static)

        found = _try_stored(path, key, leaves, run)
        if found is not None:
            return found
        # processes sharing the folder: the first compiles and writes, the others wait and load its file
        with _kernel_lock(path):
            found = _try_stored(path, key, leaves, run)
            if found is not None:
                return found
            with _fresh_compilation():
                f = jax.jit(flat).lower(*leaves).compile()
            _write(path, key, f)
        _LOADED[key] = f
        return f, None


def _try_stored(path: Path, key: str, leaves, run: bool):
    """(the stored kernel, its outputs or None) when ``path`` holds a kernel for ``key`` that runs, else None."""
    f = _read(path, key)
    if f is None:
        return None
    try:   # a loaded program that cannot run (e.g. written by an older version of this module): never again
        out = jax.block_until_ready(f(*leaves))
    except jax.errors.JaxRuntimeError as e:
        log.warning("%s: the stored kernel does not run (%s); compiling it again", path, str(e)[:200])
        return None
    _LOADED[key] = f
    return f, (out if run else None)


@contextlib.contextmanager
def _kernel_lock(path: Path):
    """The stored kernel's inter-process lock; where no lock can be made (a read-only folder) the kernel
    is compiled without it (and, as before, not stored)."""
    stack = contextlib.ExitStack()
    try:
        stack.enter_context(file_lock(path))
    except OSError as e:
        log.warning("%s: cannot lock the stored kernel (%s); compiling without the lock", path, e)
    with stack:
        yield


@contextlib.contextmanager
def _fresh_compilation():
    """Compile without JAX's persistent compilation cache: an executable that was itself loaded from that
    cache serializes without its compiled functions on the CPU backend (loading it then fails with
    "Function ... not found"), so a stored kernel is always compiled afresh (once, when it is written)."""
    from jax._src import compilation_cache

    old = jax.config.jax_compilation_cache_dir
    if not old:
        yield
        return
    jax.config.update("jax_compilation_cache_dir", None)
    compilation_cache.reset_cache()
    try:
        yield
    finally:
        jax.config.update("jax_compilation_cache_dir", old)
        compilation_cache.reset_cache()


@dataclass(frozen=True)
class JaxCacheParams:
    """``jax_cache:`` in ``conf/config.yaml`` (see :func:`enable_compilation_cache`); the config
    points both folders into ``${cache_dir}``, None turns a cache off."""

    dir: Optional[str] = None              # JAX's persistent compilation cache
    kernel_dir: Optional[str] = None       # the search kernels' whole executables
    min_compile_time_s: float = 0.0        # cache kernels that took at least this long to compile
    min_entry_size_bytes: int = 0          # ... and are at least this large
    # JAX's size limit of the compilation cache (least recently used entries go first). Any limit turns
    # on JAX's file lock around every read and write of the folder, so processes sharing it never read
    # an entry half-written; -1 (no limit) turns the lock off too, 0 turns the cache off.
    max_size_bytes: int = 16 * 2**30


def enable_compilation_cache(params: JaxCacheParams | None) -> Path | None:
    """Turn on JAX's persistent compilation cache at ``params.dir`` (the config's ``jax_cache.dir``, default
    ``${cache_dir}/jax_cache``), so a second run of any task loads its compiled kernels from disk
    instead of compiling them again. ``jax_cache.dir=null`` turns it off. The directory holds only
    compiled executables and is safe to delete (the next run recompiles). Entries are written for
    kernels that took at least ``jax_cache.min_compile_time_s`` to compile (default 0: every kernel,
    since on CPU many small ones add up) and are at least ``jax_cache.min_entry_size_bytes`` large.
    ``jax_cache.max_size_bytes`` (default 16 GiB) bounds the folder and makes JAX lock it while reading or
    writing an entry, so processes sharing it never read one half-written.
    The search kernels' executables are also stored whole in ``jax_cache.kernel_dir`` (default
    ``${cache_dir}/jax_kernels``; :mod:`convsynth_jax.kernel_cache`), so a second run skips their
    tracing and lowering too; null turns that off, and so does ``jax_cache.dir=null``.
    Returns the directory (or None when disabled; ``params`` None: disabled)."""
    path = params.dir if params is not None else None
    if not path:
        _set_cache_dir(jax, None)  # off, also when an earlier task of this process turned it on
        set_kernel_dir(None)
        return None
    path = Path(str(path)).expanduser().resolve()
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise ConfigError(f"jax_cache.dir={path}: cannot create the compilation cache directory ({e})") from None
    jax.config.update("jax_persistent_cache_min_compile_time_secs", float(params.min_compile_time_s))
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", int(params.min_entry_size_bytes))
    if jax.config.jax_compilation_cache_max_size != int(params.max_size_bytes):
        jax.config.update("jax_compilation_cache_max_size", int(params.max_size_bytes))
        _set_cache_dir(jax, None)  # read again when the folder is set below
    _set_cache_dir(jax, str(path))
    kdir = params.kernel_dir
    set_kernel_dir(Path(str(kdir)).expanduser().resolve() if kdir else None)
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
