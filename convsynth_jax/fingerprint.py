"""Content fingerprints: the key of every cached result is what it was computed from and by which code.

A cache that keys its entries by names (clip names, a corpus folder, a hand-bumped version string)
returns stale results when a file is edited in place or when two corpora name their sessions alike.
Every cache of the framework (annotations, motion graphs, the paper's graph statistics, the results
store) is instead keyed by

- the **content** it was computed from: :func:`file_digest` (a file's bytes), :func:`content_digest`
  (arrays, dataclasses, tables, parameters; the motion and labels a model is fitted on), and a
  corpus's :func:`convsynth_jax.io.corpus.corpus_fingerprint` (every motion, audio and transcript file
  and ``corpus.json``, which holds the synthetic generator's configuration);
- the **code** that computed it: :func:`code_fingerprint` (the package version and the source of the
  modules the result depends on; the whole package by default).

Hashing is cheap: a file's bytes are hashed once per process and remembered by (path, size,
modification time, change time, inode), so a file edited in place (which always changes its change
time, even when the modification time is set back) is hashed again; SHA-256 reads a 200 MB corpus in
about 0.4 s.
"""
from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import threading
from pathlib import Path

import numpy as np

# the modules of the layers below io (pyproject.toml's import-linter layers): every result depends on them
FOUNDATION = ("errors", "utils", "rotations", "schema", "rig", "easing", "skeleton", "kinematics", "kernel_cache",
              "manifest", "paper_values", "seeding", "fingerprint")

_PACKAGE = Path(__file__).resolve().parent
_digests: dict = {}
_lock = threading.Lock()


def stable_hash(*parts, length: int = 12) -> str:
    """A short stable hash of parameters: dataclasses, dicts, lists and scalars (key order does not
    matter). Arrays and tables inside go through :func:`content_digest` (never their truncated repr)."""
    def plain(x):
        if dataclasses.is_dataclass(x) and not isinstance(x, type):
            return {f.name: plain(getattr(x, f.name)) for f in dataclasses.fields(x)}
        if isinstance(x, dict):
            return {str(k): plain(v) for k, v in x.items()}
        if isinstance(x, (list, tuple)):
            return [plain(v) for v in x]
        if isinstance(x, (np.ndarray, np.generic)) and np.ndim(x) > 0 or _is_table(x):
            return content_digest(x)
        return x

    text = json.dumps([plain(p) for p in parts], sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:length]


def _is_table(x) -> bool:
    return type(x).__name__ in ("DataFrame", "Series") and hasattr(x, "to_numpy")


def file_digest(path: str | Path) -> str:
    """SHA-256 of a file's bytes (hex). Remembered per process by (resolved path, size, mtime, ctime,
    inode): an unchanged file is read once, a file edited in place is read again."""
    p = Path(path).resolve()
    st = p.stat()
    stamp = (str(p), st.st_size, st.st_mtime_ns, st.st_ctime_ns, st.st_ino)
    with _lock:
        found = _digests.get(stamp)
    if found is not None:
        return found
    h = hashlib.sha256()
    with open(p, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 22), b""):
            h.update(block)
    digest = h.hexdigest()
    with _lock:
        _digests[stamp] = digest
    return digest


def content_digest(obj) -> str:
    """SHA-256 (hex) of a value's content: arrays (dtype, shape, bytes; JAX arrays too), pandas tables
    (columns, index, values), dataclasses (class name and every field), mappings (in key order),
    sequences, paths (as text) and scalars. Two values with equal content have equal digests."""
    h = hashlib.sha256()
    _update(h, obj)
    return h.hexdigest()


def _update(h, x) -> None:
    if x is None or isinstance(x, (bool, int, float, str, Path)):
        h.update(f"{type(x).__name__}:{x!r};".encode())
    elif isinstance(x, bytes):
        h.update(b"bytes:%d;" % len(x) + x)
    elif isinstance(x, (np.ndarray, np.generic)) or hasattr(x, "__array__") and hasattr(x, "dtype"):
        a = np.ascontiguousarray(np.asarray(x))
        if a.dtype == object:
            h.update(f"objects{a.shape};".encode())
            for v in a.ravel():
                _update(h, v)
        else:
            h.update(f"array:{a.dtype.str}{a.shape};".encode())
            h.update(a.tobytes())
    elif _is_table(x):
        h.update(f"{type(x).__name__};".encode())
        if type(x).__name__ == "DataFrame":
            _update(h, [str(c) for c in x.columns])
            for c in x.columns:
                _update(h, x[c].to_numpy())
        else:
            _update(h, x.to_numpy())
        _update(h, x.index.to_numpy())
    elif dataclasses.is_dataclass(x) and not isinstance(x, type):
        h.update(f"{type(x).__qualname__}{{".encode())
        for f in dataclasses.fields(x):
            h.update(f.name.encode() + b"=")
            _update(h, getattr(x, f.name))
        h.update(b"}")
    elif isinstance(x, dict):
        h.update(b"{")
        for k in sorted(x, key=repr):
            _update(h, k)
            _update(h, x[k])
        h.update(b"}")
    elif isinstance(x, (list, tuple)):
        h.update(f"{type(x).__name__}[{len(x)}".encode())
        for v in x:
            _update(h, v)
        h.update(b"]")
    elif isinstance(x, (set, frozenset)):
        _update(h, sorted(x, key=repr))
    else:
        h.update(f"{type(x).__qualname__}:{x!r};".encode())


@functools.lru_cache(maxsize=None)
def code_fingerprint(*parts: str) -> str:
    """The package version and a hash of source files of the package, so that results computed by other
    code are never reused. No ``parts``: every source file (any edit of the library changes it). With
    ``parts`` (subpackage or module names, e.g. ``"io", "annotate"``): those and the foundation modules
    (:data:`FOUNDATION`), for a cache whose results depend on them only (the import-linter layers keep a
    layer's imports below it). The package's data files (``resources/``) count in both."""
    from . import __version__

    h = hashlib.sha256(__version__.encode())
    if parts:
        names = sorted(set(FOUNDATION) | set(parts))
        files = []
        for n in names:
            d = _PACKAGE / n
            files += sorted(d.rglob("*.py")) if d.is_dir() else [_PACKAGE / f"{n}.py"]
        h.update(("parts:" + ",".join(names)).encode())
    else:
        files = sorted(_PACKAGE.rglob("*.py"))
    files += sorted(f for f in (_PACKAGE / "resources").rglob("*") if f.is_file())  # data the code reads
    for f in files:
        h.update(str(f.relative_to(_PACKAGE)).encode() + b"\0" + f.read_bytes() + b"\0")
    return h.hexdigest()


def forget_digests() -> None:
    """Drop the remembered file digests (tests; a long-lived process that wants to re-read)."""
    with _lock:
        _digests.clear()


__all__ = ["FOUNDATION", "code_fingerprint", "content_digest", "file_digest", "forget_digests", "stable_hash"]
