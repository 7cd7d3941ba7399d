"""The paper's stochastic greedy search (Section 7.1) with depth-first matching (Section 7.2).

The window is cut into blocks at the boundaries of the own-channel constraints. From ``n_start``
random start states, each block is matched by a depth-first traversal that follows out-edges
(cheapest first), checking the per-frame constraint mask at every step and the PC peak when its
window closes; at most ``max_paths_per_start`` complete block paths are kept per start state and
``max_expansions`` bound the work. Of all block paths found, ``n_save`` are sampled (cheaper ones
likelier: Gumbel top-k on -cost / temperature); their end states start the next block. The best
complete path is returned; if no path survives a block the search reports which one.

With ``search.lookahead`` (ours, default) a step is taken only if the window can still be completed
from it (:mod:`convsynth_jax.search.feasible`, the beam's look-ahead) and an unsolvable window fails
at once. With ``search.matching=paper`` each step also applies the paper's whole-segment rule (entry windows,
contiguity, placement; :func:`convsynth_jax.search.constraints.paper_channel_step`, the same rule
as the beam kernel's) and a candidate carries the two entry flags instead of the peak flag.
"""
from __future__ import annotations

import dataclasses
import time

import numpy as np

from .constraints import (Constraints, constrained, is_peak_state, median_synthetic_cost, paper_channel_step, segment_info,
                          state_ok_matrix)
from .result import SearchResult, failed_segment_at, failure_reason, path_stats
from .params import SearchParams


def _blocks(c: Constraints) -> list[tuple[int, int]]:
    cuts = {0, c.num_frames}
    for s in c.segments:
        if s["channel"] == "own":
            # a block reaches one frame past the segment's end margin, so its end is checked inside it
            for x in (s["start"] - c.tol, s["end"] + c.tol + 1):
                if 0 < x < c.num_frames:
                    cuts.add(int(x))
    cuts = sorted(cuts)
    return list(zip(cuts[:-1], cuts[1:]))


def _paper_rule(graph, c: Constraints):
    """step(t, x, y, synthetic, flags, first) -> (ok, flags) of ``matching=paper`` for scalars."""
    info = segment_info(graph)
    own_l, par_l = graph.own_label.astype(np.int32), graph.partner_label.astype(np.int32)
    pa = c.paper
    own_a, par_a = pa.own(), pa.partner()

    def step(t, x, y, synthetic, flags, first):
        ix, iy = info[x], info[y]
        syn, fst = np.bool_(synthetic), np.bool_(first)
        ok_o, fo = paper_channel_step(own_l[x], ix[0], ix[1], own_l[y], iy[0], iy[1], iy[2], syn, fst, t,
                                      np.bool_(flags[0]), tuple(a[t] for a in own_a), pa.own_codes, c.tol)
        ok_p, fp = paper_channel_step(par_l[x], ix[3], ix[4], par_l[y], iy[3], iy[4], -1, syn, fst, t,
                                      np.bool_(flags[1]), tuple(a[t] for a in par_a), pa.par_codes, c.tol)
        return bool(ok_o and ok_p), (bool(fo), bool(fp))

    return step


def stochastic_greedy_search(graph, constraints: Constraints, params: SearchParams, seed: int = 0,
                             start_states=None) -> SearchResult:
    """``start_states``: graph states the path may start from (None: any), e.g. the successors of the
    previous window's last state when windows are chained (tasks/converse.py)."""
    t_begin = time.perf_counter()
    rng = np.random.default_rng(seed)
    n_start, n_save = int(params.n_start), int(params.n_save)
    max_paths, max_exp = int(params.max_paths_per_start), int(params.max_expansions)
    # wall-clock bound only when asked for: by default results do not depend on the machine's speed
    budget = float(params.time_budget) if params.time_budget is not None else float("inf")
    temperature = float(params.temperature)
    temp = max(temperature * median_synthetic_cost(graph), 1e-6)
    ok = state_ok_matrix(graph, constraints)
    peak = is_peak_state(graph)
    c = constraints
    indptr, indices, costs = graph.indptr, graph.indices, graph.cost
    order = {}

    max_deg = int(params.max_degree)

    syn_all = graph.synthetic
    paper = _paper_rule(graph, c) if c.paper is not None else None

    def edges(s):
        if s not in order:
            a, b = indptr[s], indptr[s + 1]
            k = np.argsort(costs[a:b], kind="stable")[:max_deg]
            order[s] = (indices[a:b][k], costs[a:b][k], syn_all[a:b][k])
        return order[s]

    def fail(frame):
        return SearchResult(False, None, float("inf"), 0, c.total, 0, frame, failed_segment_at(c, frame),
                            time.perf_counter() - t_begin, "dfs", failure=failure_reason(c, frame, "dfs"))

    feas = None
    if params.lookahead and constrained(c):   # ours: keep only steps that can still complete the window (search/feasible.py)
        from .beam import lookahead

        f_dev, solvable = lookahead(graph, c, max_deg)
        if not solvable and params.on_failure == "best_effort":   # search/relax.py takes over
            return SearchResult(False, None, float("inf"), 0, c.total, 0, seconds=time.perf_counter() - t_begin,
                                method="dfs", failure=f"look-ahead: no path of the graph (each state's {max_deg} "
                                "cheapest edges) meets every constraint of the window")
        if not solvable:   # the search without it names the constraint where its paths die
            res = stochastic_greedy_search(graph, c, dataclasses.replace(params, lookahead=False), seed, start_states)
            if not res.success:
                res.failure += ("; look-ahead: no path of the graph (each state's "
                                f"{max_deg} cheapest edges) meets every constraint of the window")
            res.seconds = time.perf_counter() - t_begin
            return res
        feas = np.asarray(f_dev)

    def completable(t, u, fl):
        if feas is None:
            return True
        bits = int(fl[0]) | (int(fl[1]) << 1) if isinstance(fl, tuple) else int(fl)
        return bool(feas[t, u] >> bits & 1)

    if paper is not None:
        first = np.array([s for s in np.flatnonzero(ok[0]) if paper(0, s, s, False, (False, False), True)[0]
                          and completable(0, s, paper(0, s, s, False, (False, False), True)[1])], np.int64)
    else:
        first = np.array([s for s in np.flatnonzero(ok[0])
                          if completable(0, s, bool(c.peak_window[0] and peak[s]))], np.int64)
    if start_states is not None:
        first = first[np.isin(first, np.asarray(start_states, np.int64))]
    if first.size == 0:
        return fail(0)
    starts = rng.choice(first, size=min(n_start, first.size), replace=False)
    # a candidate: (path list, cost, flag): the peak flag, or (own, partner) entry flags with paper
    if paper is not None:
        frontier = [([int(s)], 0.0, paper(0, int(s), int(s), False, (False, False), True)[1]) for s in starts]
    else:
        frontier = [([int(s)], 0.0, bool(c.peak_window[0] and peak[s])) for s in starts]
        frontier = [f for f in frontier if not (c.peak_check[0] and not f[2])]
    for (b0, b1) in _blocks(c):
        if b0 == 0:
            b0 = 1
        if b1 <= b0:
            continue
        found = []
        per_start = max(1000, max_exp // max(1, len(frontier)))
        for path, cost, flag in frontier:
            kept = 0
            expansions = 0
            stack = [(path[-1], b0, cost, flag, [])]
            while stack and kept < max_paths and expansions < per_start and time.perf_counter() - t_begin < budget:
                s, t, cst, fl, seg = stack.pop()
                if t == b1:
                    found.append((path + seg, cst, fl))
                    kept += 1
                    continue
                tg, cc, sy = edges(s)
                for u, w, y in zip(tg[::-1], cc[::-1], sy[::-1]):  # push expensive first: cheapest popped first
                    u = int(u)
                    if not ok[t, u]:
                        continue
                    if paper is not None:
                        good, f2 = paper(t, s, u, y, fl, False)
                        if not good:
                            continue
                    else:
                        f2 = (False if c.peak_reset[t] else fl) or bool(c.peak_window[t] and peak[u])
                        if c.peak_check[t] and not f2:
                            continue
                    if not completable(t, u, f2):
                        continue
                    expansions += 1
                    stack.append((u, t + 1, cst + float(w), f2, seg + [u]))
        if not found:
            return fail(b0)
        cost_arr = np.array([f[1] for f in found])
        score = -cost_arr / temp + rng.gumbel(size=cost_arr.size)
        keep = np.argsort(-score)[:n_save]
        frontier = [found[k] for k in keep]
    best = min(frontier, key=lambda f: f[1])
    path = np.asarray(best[0], np.int64)
    total, tc, at = path_stats(graph, path)
    return SearchResult(True, path, total, len(tc), c.total, c.total, None, None, time.perf_counter() - t_begin,
                        "dfs", tc, at)
