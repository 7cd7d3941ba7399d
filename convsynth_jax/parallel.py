"""Per-session work spread over processes: generating and annotating a corpus session by session.

Sessions are independent (each draws from its own seeded streams), so the results, gathered in input
order, are the same bytes whatever the number of processes. Worker processes are *spawned*, never
forked: JAX runs threads that a fork would copy half-way.

The number of processes: the ``workers`` argument, else ``$CONVSYNTH_WORKERS``, else one per CPU core
this process may use; never more than the number of items, and no pool at all for one worker or
fewer than ``min_items`` items (starting a process costs about a second of imports).

A spawned process starts by importing the caller's main module again. When that cannot be done (a
script read from standard input, ``python - <<EOF``; or a function defined in a main module that has
no file: ``python -c``, an interactive session, a notebook), the work runs in this process instead,
with one ``RuntimeWarning`` (the same results: they do not depend on the number of processes).
"""
from __future__ import annotations

import concurrent.futures as cf
import functools
import multiprocessing
import os
import sys
import warnings
from typing import Callable, Iterable, Sequence, TypeVar

T = TypeVar("T")
R = TypeVar("R")

ENV = "CONVSYNTH_WORKERS"
_WARNED: set = set()   # the reasons already warned about in this process (one warning each)


def available_cpus() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def resolve_workers(workers: int | None, num_items: int, min_items: int = 4) -> int:
    """How many processes to use for ``num_items`` items (1: run in this process)."""
    if workers is None:
        env = os.environ.get(ENV, "").strip()
        if env:
            try:
                workers = int(env)
            except ValueError:
                raise ValueError(f"${ENV} must be a whole number of processes, got {env!r}") from None
        else:
            workers = available_cpus() if num_items >= min_items else 1
    if workers < 1:
        raise ValueError(f"the number of worker processes must be at least 1, got {workers}")
    return max(1, min(int(workers), num_items))


def _target(fn):
    """The function a ``functools.partial`` (nested or not) finally calls."""
    while isinstance(fn, functools.partial):
        fn = fn.func
    return fn


def spawn_unavailable(fn=None) -> str | None:
    """Why spawned processes could not run ``fn`` from this interpreter (None: they can). A spawned
    process re-imports the main module by its module name (``python -m``) or by its file; it cannot
    when the file does not exist (``<stdin>``), and it cannot find a function of a main module that
    has neither (``-c``, an interactive session, a notebook)."""
    main = sys.modules.get("__main__")
    if main is None or getattr(main, "__spec__", None) is not None:
        return None
    path = getattr(main, "__file__", None)
    if path is not None and not os.path.isfile(path):
        return f"the main module ({path}) is not a file that a worker process can import again"
    if path is None and getattr(_target(fn), "__module__", None) == "__main__":
        return "the function is defined in a main module without a file (python -c, an interactive session)"
    return None


def ordered_map(fn: Callable[[T], R], items: Sequence[T] | Iterable[T], workers: int | None = None,
                min_items: int = 4, on_done: Callable[[], None] | None = None) -> list[R]:
    """``[fn(x) for x in items]``, over ``resolve_workers(...)`` spawned processes when that is more
    than one (``fn`` and the items must then pickle). ``on_done`` is called once per finished item
    (a progress bar's update). An exception in any item is raised here, the pool shut down. Where
    worker processes cannot be started for this caller (:func:`spawn_unavailable`), the items run
    here with one warning."""
    items = list(items)
    n = resolve_workers(workers, len(items), min_items)
    if n > 1:
        why = spawn_unavailable(fn)
        if why is not None and why not in _WARNED:
            _WARNED.add(why)
            warnings.warn(f"running {len(items)} items in this process instead of {n} worker processes: {why} "
                          f"(pass workers=1 or set ${ENV}=1 to choose this and silence the warning)",
                          RuntimeWarning, stacklevel=2)
        if why is not None:
            n = 1
    if n <= 1:
        out = []
        for x in items:
            out.append(fn(x))
            if on_done is not None:
                on_done()
        return out
    ctx = multiprocessing.get_context("spawn")
    with cf.ProcessPoolExecutor(max_workers=n, mp_context=ctx) as pool:
        futures = [pool.submit(fn, x) for x in items]
        try:
            for f in cf.as_completed(futures):
                f.result()  # raise the first failure as soon as it happens
                if on_done is not None:
                    on_done()
        except BaseException:
            for f in futures:
                f.cancel()
            raise
        return [f.result() for f in futures]
