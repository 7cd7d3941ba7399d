"""Per-session work spread over processes: generating and annotating a corpus session by session.

Sessions are independent (each draws from its own seeded streams), so the results, gathered in input
order, are the same bytes whatever the number of processes. Worker processes are *spawned*, never
forked: JAX runs threads that a fork would copy half-way.

The number of processes: the ``workers`` argument, else ``$CONVSYNTH_WORKERS``, else one per CPU core
this process may use; never more than the number of items, and no pool at all for one worker or
fewer than ``min_items`` items (starting a process costs about a second of imports).
"""
from __future__ import annotations

import concurrent.futures as cf
import multiprocessing
import os
from typing import Callable, Iterable, Sequence, TypeVar

T = TypeVar("T")
R = TypeVar("R")

ENV = "CONVSYNTH_WORKERS"


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


def ordered_map(fn: Callable[[T], R], items: Sequence[T] | Iterable[T], workers: int | None = None,
                min_items: int = 4, on_done: Callable[[], None] | None = None) -> list[R]:
    """``[fn(x) for x in items]``, over ``resolve_workers(...)`` spawned processes when that is more
    than one (``fn`` and the items must then pickle). ``on_done`` is called once per finished item
    (a progress bar's update). An exception in any item is raised here, the pool shut down."""
    items = list(items)
    n = resolve_workers(workers, len(items), min_items)
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
