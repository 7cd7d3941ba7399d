"""Small helpers shared across the library: atomic writes, inter-process file locks, JSON encoding.

Shared caches (the synthetic corpus, annotations, motion graphs, stored kernels) follow one rule: a
reader takes an entry only when it is complete (entries appear by an atomic rename), and a process
that finds an entry missing computes it while holding the entry's lock (:func:`file_lock`), after
looking again, so several processes started together on one empty cache compute each entry once."""
from __future__ import annotations

import contextlib
import errno
import json
import os
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from .errors import ConvSynthError


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_path(path: str | Path, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; rename it onto ``path`` only if the block succeeds.

    Nothing is left half-written: on any exception the temporary file is removed.
    """
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=suffix or path.suffix, dir=path.parent)
    except OSError as e:
        raise write_error(e, path) from None
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        if tmp_path.exists():
            os.chmod(tmp_path, 0o666 & ~_umask())
        os.replace(tmp_path, path)
    except BaseException as e:
        with contextlib.suppress(OSError):
            tmp_path.unlink()
        if isinstance(e, OSError) and write_error(e, path) is not e:
            raise write_error(e, path) from None
        raise


# errno values of a write that the user fixes outside the program: read-only, no permission, disk full, quota
WRITE_FAULTS = {errno.EACCES, errno.EPERM, errno.EROFS, errno.ENOSPC, errno.EDQUOT, errno.EFBIG}


def write_error(e: OSError, path: Path) -> BaseException:
    """The project's :class:`~convsynth_jax.errors.WriteError` for a failed write of ``path`` when ``e`` is
    a fault the user fixes outside the program (:data:`WRITE_FAULTS`), else ``e`` itself."""
    from .errors import WriteError

    if isinstance(e, ConvSynthError) or e.errno not in WRITE_FAULTS:
        return e

    why = {errno.ENOSPC: "the disk is full", errno.EDQUOT: "the disk quota is exceeded",
           errno.EROFS: "the file system is read-only", errno.EFBIG: "the file is too large"}.get(
        e.errno, f"no permission to write in {path.parent}")
    err = WriteError(f"cannot write ({why}: {e.strerror or e}); nothing was written", path)
    err.errno = e.errno
    return err


def lock_path(path: str | Path) -> Path:
    """The lock file of ``path``: ``.<name>.lock`` beside it."""
    path = Path(path)
    return path.parent / f".{path.name}.lock"


@contextlib.contextmanager
def file_lock(path: str | Path, timeout_s: float | None = None) -> Iterator[Path]:
    """Hold the inter-process lock of ``path`` (an exclusive ``flock`` on :func:`lock_path`, through
    the ``filelock`` package) for the block; wait for it as long as another process holds it, or at
    most ``timeout_s`` seconds (then :class:`~convsynth_jax.errors.ConvSynthError` naming the lock
    file). The operating system releases the lock when its holder exits, even when killed, so a
    crashed process never leaves a stale lock. Yields the lock file's path. The lock file stays
    (removing it while another process waits on it would break the lock)."""
    from filelock import FileLock, Timeout

    from .errors import ConvSynthError

    lp = lock_path(path)
    lp.parent.mkdir(parents=True, exist_ok=True)
    lock = FileLock(str(lp), timeout=-1 if timeout_s is None else float(timeout_s), thread_local=False)
    try:
        lock.acquire()
    except Timeout:
        raise ConvSynthError(f"another process has held this lock for more than {timeout_s} s", lp) from None
    try:
        yield lp
    finally:
        lock.release()


def replace_dir(tmp: str | Path, target: str | Path) -> Path:
    """Put the complete folder ``tmp`` at ``target`` by renames: an existing ``target`` is first
    renamed aside (then deleted), so ``target`` is never seen half-deleted or half-written."""
    tmp, target = Path(tmp), Path(target)
    old = None
    if target.exists():
        old = target.parent / f".{target.name}.old-{os.getpid()}-{time.monotonic_ns()}"
        os.replace(target, old)
    os.replace(tmp, target)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
    return target


def write_text_atomic(path: str | Path, text: str) -> Path:
    with atomic_path(path) as tmp:
        tmp.write_text(text)
    return Path(path)


def _json_default(obj: Any) -> Any:
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (np.floating,)):
        return float(obj)
    if isinstance(obj, (np.bool_,)):
        return bool(obj)
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    if hasattr(obj, "item") and callable(obj.item):  # jax scalars
        return obj.item()
    raise TypeError(f"not JSON serializable: {type(obj)!r}")


def write_json_atomic(path: str | Path, data: Any) -> Path:
    return write_text_atomic(path, json.dumps(data, indent=2, default=_json_default, sort_keys=False) + "\n")


def show_progress_bar(progress: bool, stream=None) -> bool:
    """Whether to draw a progress bar: when ``progress`` asks for one and the stream (stderr) is a
    terminal. Redirected to a file or a pipe, a bar's carriage returns and escape codes would be
    written into the log; the tasks log a line per step instead."""
    import sys

    stream = sys.stderr if stream is None else stream
    try:
        return bool(progress) and bool(stream.isatty())
    except (AttributeError, ValueError):  # no isatty, or a closed stream
        return False


def save_figure(fig, path, dpi: int = 110) -> Path:
    """Write matplotlib Figure ``fig`` to ``path`` in the format its suffix names (png, pdf, svg),
    at ``dpi``; atomically (a temporary file renamed onto ``path``), so a failed write leaves no
    half-written figure. Returns the path. The one way a figure reaches a file: the figures layer
    re-exports it, and a method below it (a model's loss curve) calls it here."""
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=dpi, format=path.suffix.lstrip(".").lower() or "png")
    return path
