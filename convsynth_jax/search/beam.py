"""Vectorized JAX search: a frame-synchronous stochastic beam over a padded adjacency.

Each output frame the B beam paths expand along their out-edges (each state's at most D cheapest,
kept cheapest first); candidates that break the frame's constraint mask die; B survivors are drawn
without replacement with probabilities proportional to exp(-cost / temperature) (Gumbel top-k), so
cheap paths are likelier but not certain: the stochastic greedy selection of the paper, done for all
paths at once. The per-frame work is kept small in three ways:

* **Candidate budget.** Most states have one out-edge (the original transition) and a few key states
  have many, so a dense B x D block is mostly padding. Instead the candidates of a frame fill
  ``max_candidates`` (M) slots path by path, in beam order, each path contributing its e_b = min(deg_b,
  r*) cheapest edges, where r* is the largest edge count such that sum_b min(deg_b, r*) <= M: when the
  beam's edges do not all fit, the most expensive ranks are dropped for every path alike. The slot
  layout is computed with a histogram, a cumulative sum and a cumulative max (no sort).
* **Noise pool.** Slot m of frame t draws the Gumbel noise ``pool[offset_t + m]`` from one pool of
  N = 4 M draws, with one random offset per frame, instead of fresh draws per candidate (threefry
  for B x D draws per frame cost more than the search itself on CPU). Within a frame all draws are
  distinct; across frames the offsets and the re-ordered beam make a repeated pairing unlikely to
  matter.
* **State deduplication.** Two paths that end in the same graph state with the same peak flag have
  the same future, so only the better-scored one is kept (hash table of H slots keyed by
  ``2 * state + flag``; H >= 2 S on small graphs makes it exact, on large graphs two states exactly a
  multiple of H / 2 apart may collide, which only drops a candidate). This keeps the beam diverse at
  low temperature, so it solves more windows without sampling hot.

The next beam is the top B of the M scores (``lax.top_k``, in descending order, which is the beam
order of the next frame). The frame count is padded to a multiple of 16 and the state count to a
multiple of 4096, so one compile serves all windows of one length on every LOO fold's graph. The path
is traced back inside the kernel; only the path and the edge ranks it used come back to the host.

Modules: this one has the method (attempts, retries, look-ahead, results) and the graph preparation
(padding, the per-graph cache, shapes shared across graphs); :mod:`.beam_kernel` the jitted kernels
and their padded inputs; :mod:`.graph_arrays` the flat edge tables and the kernels' graph arguments.
Kernel arguments are named tuples (``GraphArrays``, ``PaperGraphArrays``, ``WindowInputs``).
:func:`convsynth_jax.testing.search_reference.reference_beam_search` does the same search with plain NumPy
loops and the same noise; tests require identical paths.
"""
from __future__ import annotations

import dataclasses
import time
from functools import partial

import jax
import numpy as np

from .. import kernel_cache
from ..errors import ConfigError, GraphError
from .beam_kernel import (FRAME_BUCKET, PaperInputs, WindowInputs, _beam_kernel,  # noqa: F401  (re-exported)
                          _lookahead_beam_kernel, noise, padded_inputs, prng_key, sizes)
from .constraints import Constraints, constrained, median_synthetic_cost, segment_info
from .feasible import feasibility, lookahead_capacity, num_flags, solvable
from .graph_arrays import (CODE_BITS, GraphArrays, HostGraph, PaperGraphArrays, PreparedGraph,  # noqa: F401
                           kept_degrees, kept_edges, state_codes)
from .params import SearchParams
from .result import SearchResult, failed_segment_at, failure_reason
from .rules import start_rule, unpack_code  # noqa: F401  (unpack_code re-exported)

STATE_BUCKET = 4096  # graphs are padded to a multiple of this many states, so LOO folds share compiles


def padded_states(num_states: int) -> int:
    """State count of the kernels' arrays: a multiple of STATE_BUCKET with at least one padding state
    (no edges, never a start state; the look-ahead points forbidden edges at the last one)."""
    return num_states + 1 + (-(num_states + 1) % STATE_BUCKET)


EDGE_BUCKET = 16384   # the flat edge arrays are padded to a multiple of this (compiles shared across folds)


_CACHE: list = []  # small LRU of (graph, max_degree, PreparedGraph)


def _prepare(graph, max_degree, shape=None) -> PreparedGraph:
    """The graph made ready for the kernels (cached). ``shape``: (states, edges, D) to pad to at least
    (share_shapes); None: the graph's own."""
    for g, d, prep in _CACHE:
        if g is graph and d == max_degree and shape is None:
            return prep
    if graph.num_states >= 2 ** (31 - CODE_BITS):
        raise GraphError(f"graph too large for the packed beam search ({graph.num_states} states, "
                         f"at most {2 ** (31 - CODE_BITS) - 1})")
    first, deg, tgt, cost, syn, D = kept_edges(graph, max_degree)
    code = state_codes(graph)
    packed = tgt << CODE_BITS | code[tgt]
    S_pad, E_pad, D_k = _own_shape(graph.num_states, tgt.size, D)
    if shape is not None:
        S_pad, E_pad, D_k = max(S_pad, shape[0]), max(E_pad, shape[1]), max(D_k, shape[2])

    def pad(x, n, v):   # host array padded to n entries (first axis) with v
        return np.concatenate([x, np.full((n - x.shape[0],) + x.shape[1:], v, x.dtype)])

    info_p, code_p = pad(segment_info(graph), S_pad, 0), pad(code, S_pad, 0)
    first_p, deg_p = pad(first, S_pad, tgt.size), pad(deg, S_pad, 0)   # padding states: no edges, never a start state
    put = jax.device_put
    host = HostGraph(first_p, deg_p, tgt, syn, info_p, code_p)
    prep = PreparedGraph(first, cost, syn, D, median_synthetic_cost(graph),
                         GraphArrays(put(first_p), put(pad(packed, E_pad, 0)), put(pad(cost, E_pad, np.inf)),
                                     put(deg_p), put(code_p)),
                         PaperGraphArrays(put(pad(syn, E_pad, False)), put(info_p)), host, graph.num_states, D_k)
    _CACHE[:] = [x for x in _CACHE if not (x[0] is graph and x[1] == max_degree)]
    _CACHE.append((graph, max_degree, prep))
    del _CACHE[:-4]
    return prep


def _own_shape(num_states: int, num_edges: int, D: int) -> tuple:
    """(padded states, padded flat edges, D) of a graph on its own: states to a multiple of
    STATE_BUCKET (at least one padding state), edges to a multiple of EDGE_BUCKET plus D (so first +
    rank never runs over)."""
    return padded_states(num_states), num_edges + (-num_edges % EDGE_BUCKET) + D, D


def share_shapes(graphs, max_degree: int) -> None:
    """Pad the kernels' arrays of ``graphs`` (e.g. both characters' graphs of one conversation) to one
    shape, so that their searches run one compiled program: a fresh process loads it once instead of
    once per graph (``kernel_cache``), and a leave-one-out fold compiles it once. The searches' results
    are unchanged: padding states are never start states and have no edges, padding edges are never
    reached, the noise of a state does not depend on the padded length (threefry draws are
    prefix-stable) and a larger D only bounds ranks no path has."""
    graphs = [g for g in graphs if g is not None]
    if len(graphs) < 2:
        return
    cached = [next((p for g2, d, p in _CACHE if g2 is g and d == max_degree), None) for g in graphs]
    if all(p is not None and len(p.peers) == len(graphs) and all(q is r for q, r in zip(p.peers, cached))
           for p in cached):
        return   # already shared (fit_fold prepares a fold's models once per condition)
    shapes = []
    for g in graphs:
        deg, D = kept_degrees(g, max_degree)
        shapes.append(_own_shape(g.num_states, int(np.minimum(deg, D).sum()), D))
    common = tuple(max(s[k] for s in shapes) for k in range(3))
    preps = [_prepare(g, max_degree, common) for g in graphs]
    for p in preps:
        object.__setattr__(p, "peers", tuple(preps))


def lookahead(graph, constraints: Constraints, max_degree: int, start_states=None, lookahead_pass: str = "auto"):
    """(feas (Tp, S_pad) uint8 device array, solvable): the look-ahead of ``search.lookahead``
    (:mod:`convsynth_jax.search.feasible`) over the beam's edge set (each state's ``max_degree``
    cheapest out-edges) and whether any start state can complete the window. ``start_states``: the
    allowed frame-0 states (None: any), as the searches take them (a chained window continues the
    previous one's path); solvable then asks for a completable one among them. ``lookahead_pass``:
    ``search.lookahead_pass`` (the same bits either way)."""
    prep = _prepare(graph, max_degree)
    inputs = padded_inputs(constraints)
    feas, ok = feasibility(prep, constraints, inputs,
                           lookahead_capacity(lookahead_pass, prep.device.state_code.shape[0]))
    if start_states is None or not bool(ok):
        return feas, bool(ok)
    paper = constraints.paper is not None
    valid0, flag0 = _start_rule(prep.device.state_code, prep.paper_device.segment_info, inputs.reqs,
                                inputs.peak_window, inputs.peak_check, inputs.paper, np.int32(graph.num_states),
                                paper=paper)
    allowed = start_mask(graph, prep.device.state_code.shape[0], start_states) & np.asarray(valid0)
    return feas, solvable(np.asarray(feas[0]), allowed, np.asarray(flag0).astype(np.uint8))


@partial(jax.jit, static_argnames=("paper",))
def _start_rule(state_code, info, reqs, pw, check, paper_arrs, num_states, paper: bool):
    """(valid (S,), flags (S,)) of every state as a frame-0 state (``rules.start_rule``, jitted)."""
    return start_rule(state_code, info, reqs, pw, check, paper_arrs, num_states, paper)


def beam_search(graph, constraints: Constraints, params: SearchParams, seed: int = 0,
                start_states=None) -> SearchResult:
    """Beam search at ``search.temperature``; if no path survives, retry at each of
    ``search.retry_temperatures`` (hotter sampling: more diverse, at the price of more synthetic
    transitions), then at every temperature again with ``search.retry_beam_size`` paths and
    ``search.retry_max_candidates`` slots (0: no wide retry). The result reports the time of all
    attempts.

    With ``search.lookahead`` (ours, default) candidates that cannot complete the window are dropped
    (:func:`lookahead`), so the first attempt succeeds whenever the window is solvable (unless the
    candidate budget drops every completable edge); an unsolvable window is reported at once, after
    one attempt without the look-ahead that names where its paths die (no retries: they cannot
    succeed).

    ``start_states``: graph states the path may start from (None: any), e.g. the successors of the
    previous window's last state when windows are chained (tasks/converse.py)."""
    t0 = time.perf_counter()
    _check_sizes(params)
    kw = {"start_states": start_states}
    temps = [float(params.temperature)] + [float(t) for t in (params.retry_temperatures or [])]
    attempts = [(params, t) for t in temps]
    if int(params.retry_beam_size) > 0:
        wide = dataclasses.replace(params, beam_size=int(params.retry_beam_size),
                                   max_candidates=max(int(params.retry_max_candidates), int(params.max_candidates)))
        attempts += [(wide, t) for t in temps]
    feas, first = None, 0
    if params.lookahead and constrained(constraints):
        # the look-ahead and the first attempt in one kernel call (one program to load per graph)
        res, feas, ok = _beam_search_once(graph, constraints, params, seed, temps[0], lookahead=True, **kw)
        if not ok:
            why = (f"look-ahead: no path of the graph (each state's {int(params.max_degree)} cheapest edges) meets "
                   "every constraint of the window")
            if params.on_failure == "best_effort":
                # best effort takes over (search/relax.py) and discards this result: no attempt to name the frame
                # where the paths die (on a long silent window that attempt cost more than the relaxation)
                res.failure = why
            else:
                res = _beam_search_once(graph, constraints, params, seed, temps[0], None, **kw)
                if not res.success:
                    res.failure = f"{res.failure}; {why}"
            res.seconds = time.perf_counter() - t0
            return res
        first = 1
    if first == 0 or not res.success:
        for k, (p, temp) in enumerate(attempts[first:], start=first):
            res = _beam_search_once(graph, constraints, p, seed + 1000 * k, temp, feas, **kw)
            if res.success:
                break
    res.seconds = time.perf_counter() - t0
    return res


def _check_sizes(params: SearchParams):
    max_deg, beam, budget = int(params.max_degree), int(params.beam_size), int(params.max_candidates)
    if min(max_deg, beam, budget) < 1:
        raise ConfigError(f"search.max_degree, search.beam_size and search.max_candidates must be >= 1 "
                          f"(got {max_deg}, {beam}, {budget})")
    return max_deg, beam, budget


def _beam_search_once(graph, constraints: Constraints, params: SearchParams, seed: int,
                      temperature: float, feas=None, lookahead: bool = False, start_states=None):
    """One beam search; ``feas``: a look-ahead to prune with (None: none). ``lookahead``: compute the
    look-ahead in the same kernel call and prune with it (:func:`_lookahead_beam_kernel`); then returns
    (result, feas, solvable). ``start_states``: the allowed frame-0 states (None: any)."""
    t0 = time.perf_counter()
    max_deg, beam, budget = _check_sizes(params)
    prep = _prepare(graph, max_deg)
    c = constraints
    paper = c.paper is not None
    B, M, N, H = sizes(graph.num_states, beam, prep.max_degree, budget, 4 if paper else 2)
    temp = max(temperature * prep.median_syn, 1e-6)
    T = c.num_frames
    inputs = padded_inputs(c)
    prune = feas is not None
    start = start_mask(graph, prep.device.state_code.shape[0], start_states)
    static = {"beam": B, "M": M, "N": N, "H": H, "D": prep.kernel_degree, "paper": paper}
    key, scalars = prng_key(seed), (np.float32(temp), np.int32(T), np.int32(graph.num_states))
    if lookahead:
        edges = prep.lookahead_edges(None if c.paper is None else (c.paper.own_codes, c.paper.par_codes),
                                     lookahead_capacity(params.lookahead_pass, prep.device.state_code.shape[0]))
        feas, ok, out = kernel_cache.call(_lookahead_beam_kernel, "lookahead_beam",
                                          (edges, key, prep.device, inputs, *scalars, prep.paper_device, start),
                                          {**static, "F": num_flags(c)})
        res = _result(prep, c, out, t0)
        return res, feas, bool(ok)
    out = kernel_cache.call(_beam_kernel, "beam",
                            (key, prep.device, inputs, *scalars, prep.paper_device if paper else None,
                             feas if prune else np.zeros((1, 1), np.uint8), start),
                            {**static, "prune": prune})
    return _result(prep, c, out, t0)


def start_mask(graph, padded: int, start_states=None) -> np.ndarray:
    """(padded,) bool: the states a path may start from (``start_states``; None: every state)."""
    if start_states is None:
        return np.ones(padded, bool)
    s = np.asarray(start_states, np.int64).ravel()
    if s.size and (s.min() < 0 or s.max() >= graph.num_states):
        raise ConfigError(f"start state out of range: {s.min()}..{s.max()} (the graph has {graph.num_states} states)")
    m = np.zeros(padded, bool)
    m[s] = True
    return m


def _result(prep, c: Constraints, out, t0) -> SearchResult:
    """The search result of a beam kernel's (path, ranks, alive) outputs."""
    T = c.num_frames
    path, rank, alive_any = (np.asarray(x)[:T] for x in out)
    if not alive_any.all():
        fail = int(np.argmin(alive_any))
        return SearchResult(False, None, float("inf"), 0, c.total, 0, fail, failed_segment_at(c, fail),
                            time.perf_counter() - t0, "beam", failure=failure_reason(c, fail, "beam"))
    path = path.astype(np.int64)
    src, rk = path[:-1], rank[1:]
    edge_cost, edge_syn = prep.edge_stats(src, rk)
    edge_cost = edge_cost.astype(np.float64)
    return SearchResult(True, path, float(edge_cost.sum()), int(edge_syn.sum()), c.total, c.total, None, None,
                        time.perf_counter() - t0, "beam", [float(x) for x in edge_cost[edge_syn]],
                        (np.flatnonzero(edge_syn) + 1).tolist())
