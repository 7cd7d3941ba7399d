"""Best effort when no path meets every constraint (``search.on_failure=best_effort``, ours).

The paper's search fails a window when no path of the graph meets all of its constraints. Best effort
returns instead a path that meets as many as it can, weighted by kind (``search.weight_pc``,
``weight_lr``, ``weight_hp``, ``weight_idle``: each kind's weight in the registry,
:mod:`convsynth_jax.annotate.kinds`), found by *greedy relaxation* with the exact
look-ahead (:mod:`convsynth_jax.search.feasible`) as the oracle:

1. order the window's constraints (:func:`~convsynth_jax.search.constraints.constraint_key`) by
   weight, heaviest first, then by start frame (deterministic);
2. walk the order and keep a constraint when the constraints kept so far plus it still leave a
   completable path (the look-ahead's ``solvable``); otherwise drop it (``relaxed``);
3. search the window with the dropped constraints left out (``build_constraints(relaxed=...)``).
   The look-ahead guarantees a path meeting every kept constraint exists, so the search (beam or
   DFS, with the window's seed) finds one.

Step 2 is done in runs (:func:`greedy_keep`): the rest of the order is tried at once and, when it
is not completable, the longest completable prefix is found by bisection, so a window with k
dropped constraints out of n costs about k log2 n look-ahead calls instead of n. Because leaving a
constraint out only frees frames (a relaxed segment is built like one of an unconstrained kind, a
relaxed idle run is free), completability is monotone in the kept set and the runs keep exactly the
constraints of the one-at-a-time walk (the reference in ``tests/test_search_relax.py``).

Greedy relaxation maximizes the kept weight heaviest first; it is not the maximum-weight subset
(that is a set-packing problem), but it never trades a clause for idle runs. The path may meet some
dropped constraints by chance: :func:`claims` replays the path through each constraint's own
encoding to say which, and :func:`best_effort_search` reports those claims; the pipeline reports
what the independent checker (``search/check.py``) confirms.
"""
from __future__ import annotations

import dataclasses
import time

import numpy as np

from ..annotate.kinds import constraint_kind, constraint_kinds
from ..errors import ConfigError
from .constraints import (Constraints, build_constraints, constraint_key, is_peak_state, label_ok,
                          requirement_arrays)
from .params import SearchParams
from .result import SearchResult

ON_FAILURE = ("fail", "best_effort")


def check_on_failure(params: SearchParams) -> str:
    mode = str(params.on_failure)
    if mode not in ON_FAILURE:
        raise ConfigError(f"search.on_failure must be one of {list(ON_FAILURE)}, got {mode!r}")
    for kind in constraint_kinds():
        if not kind.weight_of(params) >= 0:
            what = f"search.{kind.weight}" if isinstance(kind.weight, str) else f"the weight of kind {kind.name}"
            raise ConfigError(f"{what} must be >= 0, got {kind.weight_of(params)}")
    return mode


def constraint_order(keys, params: SearchParams) -> list:
    """The keys heaviest kind first, then by start frame, end frame and kind (a total order)."""
    return sorted(keys, key=lambda k: (-constraint_kind(k[0]).weight_of(params), k[1], k[2], k[0]))


def greedy_keep(order: list, completable) -> tuple[list, list]:
    """(kept, dropped) of the greedy walk over ``order`` (module docstring, step 2) in runs with
    bisection; ``completable(kept_list) -> bool`` must hold for the empty list."""
    kept, dropped = [], []
    i = 0
    while i < len(order):
        rest = order[i:]
        if completable(kept + rest):
            kept += rest
            break
        lo, hi = 0, len(rest) - 1          # kept + rest[:lo] completable, kept + rest[:hi + 1] not
        while lo < hi:
            mid = (lo + hi + 1) // 2
            if completable(kept + rest[:mid]):
                lo = mid
            else:
                hi = mid - 1
        kept += rest[:lo]
        dropped.append(rest[lo])
        i += lo + 1
    return kept, dropped


def path_meets(graph, c: Constraints, path) -> bool:
    """Does ``path`` ((T,) graph states) meet every constraint of ``c``? The constraints' own rules
    (labels, peak flag or the ``paper`` entry windows) replayed along the path on the host."""
    path = np.asarray(path, np.int64)
    own_l, par_l = graph.own_label.astype(np.int32), graph.partner_label.astype(np.int32)
    reqs = requirement_arrays(c)
    if not all(label_ok(own_l[y], par_l[y], tuple(r[t] for r in reqs)) for t, y in enumerate(path)):
        return False
    if c.paper is not None:
        from .dfs import _paper_rule

        step = _paper_rule(graph, c)
        ok, flags = step(0, int(path[0]), int(path[0]), False, (False, False), True)
        for t in range(1, len(path)):
            if not ok:
                return False
            x, y = int(path[t - 1]), int(path[t])
            syn = not (graph.clip[x] == graph.clip[y] and graph.frame[y] == graph.frame[x] + 1)
            ok, flags = step(t, x, y, syn, flags, False)
        return bool(ok)
    peak = is_peak_state(graph)
    flag = False
    for t, y in enumerate(path):
        flag = (False if c.peak_reset[t] else flag) or bool(c.peak_window[t] and peak[y])
        if c.peak_check[t] and not flag:
            return False
    return True


def claims(graph, own_segments, partner_segments, num_frames: int, fps: float, params: SearchParams, path,
           keys: list, kept: set) -> dict:
    """key -> met, as the search sees it: kept constraints are met by construction; each other one is
    replayed alone (every other constraint relaxed) along the path (:func:`path_meets`)."""
    out = {}
    for k in keys:
        if k in kept:
            out[k] = True
            continue
        alone = build_constraints(own_segments, partner_segments, num_frames, fps, params,
                                  relaxed=frozenset(keys) - {k})
        out[k] = path_meets(graph, alone, path)
    return out


def best_effort_search(search, graph, own_segments, partner_segments, num_frames: int, fps: float,
                       params: SearchParams, seed: int = 0, start_states=None) -> SearchResult:
    """The best-effort search of a window that ``search`` (beam or DFS: (graph, constraints, params,
    seed) -> SearchResult) could not solve (module docstring). The result has ``best_effort`` set,
    ``constraints_total`` / ``constraints_met`` over the full window, ``relaxed`` the dropped keys and
    ``claimed`` key -> met (:func:`claims`); it fails only when no path exists even with every
    constraint dropped, or the search misses the relaxed window (candidate budget). ``start_states``:
    the allowed frame-0 states (None: any; a chained window of ``synth/chain.py`` continues the
    previous window's path): the look-ahead then asks for completion from them, so a constraint that
    no path from there can meet (a clause already under way at the cut, placed otherwise by the
    previous window) is the one dropped."""
    from .beam import lookahead

    t0 = time.perf_counter()
    full = build_constraints(own_segments, partner_segments, num_frames, fps, params)
    keys = [constraint_key(s) for s in full.segments]
    order = constraint_order(keys, params)
    memo: dict = {}
    max_deg = int(params.max_degree)

    def completable(kept_list) -> bool:
        relaxed = frozenset(keys) - frozenset(kept_list)
        if relaxed not in memo:
            c = build_constraints(own_segments, partner_segments, num_frames, fps, params, relaxed=relaxed)
            memo[relaxed] = lookahead(graph, c, max_deg, start_states)[1]
        return memo[relaxed]

    if not completable([]):
        return SearchResult(False, None, float("inf"), 0, full.total, 0, seconds=time.perf_counter() - t0,
                            method=str(params.method), failure="best effort: no path of the graph spans the window "
                            "even without constraints", best_effort=True, relaxed=list(keys))
    kept, dropped = greedy_keep(order, completable)
    cons = build_constraints(own_segments, partner_segments, num_frames, fps, params, relaxed=frozenset(dropped))
    # the window is solvable now: no retries beyond what the method does by itself
    kw = {} if start_states is None else {"start_states": start_states}
    res = search(graph, cons, dataclasses.replace(params, on_failure="fail"), seed=seed, **kw)
    res.best_effort = True
    res.relaxed = list(dropped)
    res.constraints_total = full.total
    res.lookahead_calls = len(memo)
    if res.success:
        res.claimed = claims(graph, own_segments, partner_segments, num_frames, fps, params, res.path, keys,
                             set(kept))
        res.constraints_met = int(sum(res.claimed.values()))
        res.failure = None
    else:
        res.constraints_met = 0
        res.failure = f"best effort: the search missed the relaxed window ({res.failure})"
    res.seconds = time.perf_counter() - t0
    return res
