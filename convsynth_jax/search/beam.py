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
:func:`convsynth_jax.testing.search_reference.reference_beam_search` does the same search with plain NumPy
loops and the same noise; tests require identical paths.
"""
from __future__ import annotations

import dataclasses
import time
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from .. import kernel_cache
from ..errors import ConfigError, GraphError, LabelError
from .constraints import (Constraints, constrained, is_peak_state, label_ok, median_synthetic_cost, requirement_arrays, segment_info)
from .rules import paper_step, start_rule, unpack_code  # noqa: F401  (unpack_code: re-exported)
from .feasible import _feasible_kernel, feasibility, lookahead_edges, num_flags, pad_lookahead
from .result import SearchResult, failed_segment_at, failure_reason
from .params import SearchParams

FRAME_BUCKET = 16
STATE_BUCKET = 4096  # graphs are padded to a multiple of this many states, so LOO folds share compiles


def padded_states(num_states: int) -> int:
    """State count of the kernels' arrays: a multiple of STATE_BUCKET with at least one padding state
    (no edges, never a start state; the look-ahead points forbidden edges at the last one)."""
    return num_states + 1 + (-(num_states + 1) % STATE_BUCKET)


def kept_degrees(graph, max_degree: int):
    """(each state's out-degree (S,), D: the largest kept degree, at least 1 and at most max_degree)."""
    deg = np.diff(graph.indptr)
    return deg, int(min(max(1, deg.max() if deg.size else 1), max_degree))


def kept_edges(graph, max_degree: int = 64):
    """Each state's at most D cheapest out-edges, cheapest first (ties: CSR order), state after state,
    as flat arrays. Returns (first (S,) int32: index of the state's first kept edge, degree (S,) int32,
    targets (E,) int32, costs (E,) float32, synthetic (E,) bool, D)."""
    deg, D = kept_degrees(graph, max_degree)
    row = np.repeat(np.arange(graph.num_states), deg)
    order = np.lexsort((np.arange(row.size), graph.cost, row))      # by row, then cost, then CSR position
    rank = np.arange(row.size) - graph.indptr[row[order]]
    o = order[rank < D]
    kdeg = np.minimum(deg, D).astype(np.int32)
    first = (np.cumsum(kdeg) - kdeg).astype(np.int32)
    return (first, kdeg, graph.indices[o].astype(np.int32), graph.cost[o].astype(np.float32),
            graph.synthetic[o].astype(bool), D)


EDGE_BUCKET = 16384   # the flat edge arrays are padded to a multiple of this (compiles shared across folds)


CODE_BITS = 9  # packed edge: target << 9 | is_peak << 8 | partner label << 4 | own label


def state_codes(graph) -> np.ndarray:
    """(S,) int32: own label | partner label << 4 | is_peak << 8."""
    own, par = np.asarray(graph.own_label, np.int64), np.asarray(graph.partner_label, np.int64)
    bad = np.flatnonzero((own < 0) | (own > 15) | (par < 0) | (par > 15))
    if bad.size:
        s = int(bad[0])
        raise LabelError(f"audio label codes must lie in 0..15 for the packed beam search (own {own[s]}, "
                         f"partner {par[s]})", where=f"graph state {s} (clip {graph.clip_names[graph.clip[s]]}, "
                         f"frame {graph.frame[s]})")
    return (own | (par << 4) | (is_peak_state(graph).astype(np.int64) << 8)).astype(np.int32)


@dataclasses.dataclass(frozen=True, eq=False)
class _Prepared:
    """A graph made ready for the kernels (cached per graph object; graphs are immutable). Edges are
    flat (:func:`kept_edges`): state s's kept edges are entries first[s] .. first[s] + deg[s] - 1."""
    first: np.ndarray        # (S,) host copies, for the path's statistics
    cost: np.ndarray         # (E,)
    syn: np.ndarray          # (E,)
    max_degree: int          # D: the largest kept degree
    median_syn: float        # median synthetic edge cost: the temperature's unit
    device: tuple            # (first, packed targets+labels, costs, degrees, state codes); states padded to
    #                          STATE_BUCKET, edges to EDGE_BUCKET (+ D, so first + rank never runs over)
    paper_device: tuple      # (synthetic flags (E,), segment info (S, 5)) for search.matching=paper
    host: tuple              # (first, degrees, targets, synthetic, segment info, state codes), states padded
    num_states: int
    kernel_degree: int = 0   # the kernels' static D: max_degree, or the largest of a group sharing shapes
    peers: tuple = ()        # the group's graphs' _Prepared (share_shapes): look-ahead lists padded alike
    _edges: dict = dataclasses.field(default_factory=dict)
    _own_edges: dict = dataclasses.field(default_factory=dict)

    def edge_stats(self, src: np.ndarray, rank: np.ndarray):
        """(costs, synthetic flags) of the edges taken from states ``src`` at edge ranks ``rank``."""
        e = self.first[src] + rank
        return self.cost[e], self.syn[e]

    def lookahead_edges(self, codes=None):
        """The look-ahead's edge lists (feasible.LookaheadEdges, device arrays) for a ``paper`` window
        with (own codes, partner codes), or for ``labels`` (None); built once per codes."""
        key = None if codes is None else (int(codes[0]), int(codes[1]))
        if key not in self._edges:
            e = self.own_lookahead_edges(key)
            if self.peers:   # a group sharing one compiled kernel: every member's lists, padded alike
                own = [p.own_lookahead_edges(key) for p in self.peers]
                rows = [max(x.src[k].shape[0] for x in own) for k in range(len(e.src))]
                e = pad_lookahead(e, rows, max(x.entry.shape[0] for x in own))
            self._edges[key] = jax.tree.map(jax.device_put, e)
        return self._edges[key]

    def own_lookahead_edges(self, key):
        """This graph's look-ahead lists for ``key`` on its own (host arrays, built once per key)."""
        if key not in self._own_edges:
            self._own_edges[key] = lookahead_edges(*self.host, self.num_states, key, max_degree=self.kernel_degree)
        return self._own_edges[key]


_CACHE: list = []  # small LRU of (graph, max_degree, _Prepared)


def _prepare(graph, max_degree, shape=None) -> _Prepared:
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
    host = (first_p, deg_p, tgt, syn, info_p, code_p)
    prep = _Prepared(first, cost, syn, D, median_synthetic_cost(graph),
                     (put(first_p), put(pad(packed, E_pad, 0)), put(pad(cost, E_pad, np.inf)), put(deg_p),
                      put(code_p)),
                     (put(pad(syn, E_pad, False)), put(info_p)), host, graph.num_states, D_k)
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


def sizes(num_states: int, beam: int, max_degree: int, max_candidates: int, keys_per_state: int = 2):
    """(B, M, N, H): beam, candidate slots, noise pool size, dedup table size (a power of two; exact
    when keys_per_state * S <= H: 2 keys per state (peak flag) for ``labels``, 4 (two entry flags)
    for ``paper``)."""
    B = int(min(beam, num_states))
    M = max(int(min(max_candidates, B * max_degree)), B)
    N = 4 * M
    H = 1 << int(np.ceil(np.log2(max(min(keys_per_state * num_states, max(4 * M, 1 << 14)), 2))))
    return B, M, N, H


@partial(jax.jit, static_argnames=("beam", "M", "N", "H", "D", "paper", "prune"))
def _beam_kernel(key, first_edge, flat_packed, flat_cost, deg, state_code, reqs, pw, reset,
                 check, temp, num_frames, num_states, paper_dev, paper_arrs, feas, start, beam: int, M: int, N: int,
                 H: int, D: int, paper: bool = False, prune: bool = False):
    """Returns (path (Tp,), edge rank used into each frame (Tp,), any path alive per frame (Tp,)).
    Edges are flat (``_Prepared``): state s's kept edges, cheapest first, are entries first_edge[s] ..
    first_edge[s] + deg[s] - 1 of flat_packed / flat_cost; D is the largest kept degree.
    ``paper``: paper_dev = (synthetic (E,), segment info (S, 5)), paper_arrs = (own per-frame arrays
    (9 x (Tp,)), partner per-frame arrays, (own codes, partner codes), tol); else both unused.
    ``prune``: feas (Tp, S) uint8 is the look-ahead (feasible.py): a candidate (state, flags) at frame
    t is kept only if bit ``flags`` of feas[t, state] is set; else feas is unused. ``start`` (S_pad,) bool:
    the states a path may start from (all True: any state; a chained window: the previous window's
    last state's successors)."""
    B = beam
    # the noise of :func:`noise` (the same jitted draws, inlined: one compilation less per graph)
    init_noise, pool, offsets = _noise(key, state_code.shape[0], N, M, pw.shape[0])
    if paper:
        flat_syn, info = paper_dev
        own_a, par_a, codes, tol = paper_arrs
    valid0, flag0 = start_rule(state_code, paper_dev[1] if paper else None, reqs, pw, check, paper_arrs, num_states,
                               paper)
    valid0 &= start
    if prune:
        valid0 &= ((feas[0] >> flag0.astype(jnp.uint8)) & 1) == 1
    top0, states0 = jax.lax.top_k(jnp.where(valid0, init_noise, -jnp.inf), B)
    alive0 = jnp.isfinite(top0)
    slots = jnp.arange(M, dtype=jnp.int32)
    rows = jnp.arange(B, dtype=jnp.int32)

    def step(carry, xs):
        states, cost, flag, alive = carry
        req_t, pw_t, reset_t, check_t, off_t, t, own_t, par_t = xs
        # candidate layout: path by path (beam order), each path's e_b cheapest edges; e_b = min(deg, r*)
        d = jnp.where(alive, deg[states], 0)
        hist = jnp.zeros(D + 1, jnp.int32).at[d].add(1)
        cum = jnp.cumsum(B - jnp.cumsum(hist)[:D])                           # sum_b min(d_b, r + 1)
        rstar = jnp.sum(cum <= M)
        e = jnp.minimum(d, rstar)
        first = jnp.cumsum(e) - e                                            # first slot of each path
        row = jnp.clip(jax.lax.cummax(jnp.full((M,), -1, jnp.int32).at[first].max(rows, mode="drop")), 0, B - 1)
        j = slots - first[row]                                               # edge rank of the slot
        jc = jnp.minimum(j, D - 1)
        flat = first_edge[states[row]] + jc
        pk = flat_packed[flat]
        cand = pk >> CODE_BITS
        own, par, peak = unpack_code(pk)
        c = cost[row] + flat_cost[flat]
        valid = (j < e[row]) & label_ok(own, par, req_t)
        if paper:
            x = states[row]
            own_x, par_x, _ = unpack_code(state_code[x])
            ok, f_new = paper_step((own_x, par_x), info[x], own, par, info[cand], flat_syn[flat], jnp.zeros(M, bool), t,
                                    flag[row], own_t, par_t, codes, tol)
            valid &= ok
            key = cand * 4 + f_new
        else:
            f_new = jnp.where(reset_t, False, flag[row]) | (pw_t & peak)
            valid &= jnp.where(check_t, f_new, True)
            key = cand * 2 + f_new.astype(jnp.int32)
        if prune:
            valid &= ((feas[t][cand] >> f_new.astype(jnp.uint8)) & 1) == 1
        noise = jax.lax.dynamic_slice(pool, (off_t,), (M,))
        score = jnp.where(valid, -c / temp + noise, -jnp.inf)
        # keep only the best candidate per (state, flags): same future, so the rest is redundant
        h = key & (H - 1)
        best = jnp.full((H,), -jnp.inf, score.dtype).at[h].max(score)
        score = jnp.where(score >= best[h], score, -jnp.inf)
        top, idx = jax.lax.top_k(score, B)
        new = (cand[idx], c[idx], f_new[idx], jnp.isfinite(top))
        return new, (row[idx], jc[idx], new[0], new[1], new[3])

    init = (states0, jnp.zeros(B, jnp.float32), flag0[states0], alive0)
    rest = tuple(x[1:] for x in reqs)
    Tp = pw.shape[0]
    if paper:
        own_rest, par_rest = tuple(a[1:] for a in own_a), tuple(a[1:] for a in par_a)
    else:
        own_rest = par_rest = jnp.zeros(Tp - 1, bool)
    _, (parents, ranks, states, costs, alives) = jax.lax.scan(
        step, init, (rest, pw[1:], reset[1:], check[1:], offsets[1:], jnp.arange(1, Tp, dtype=jnp.int32),
                     own_rest, par_rest))
    # trace back the cheapest live path of the true last frame (the frames after it are padding)
    last = jnp.maximum(num_frames - 2, 0)
    b_last = jnp.argmin(jnp.where(alives[last], costs[last], jnp.inf)).astype(jnp.int32)

    def back(b, t):
        active = t <= last
        return jnp.where(active, parents[t, b], b), (states[t, b], ranks[t, b])

    b0, (path_rest, rank_rest) = jax.lax.scan(back, b_last, jnp.arange(parents.shape[0]), reverse=True)
    path = jnp.concatenate([jnp.where(num_frames > 1, states0[b0], states0[jnp.argmax(alive0)])[None], path_rest])
    rank = jnp.concatenate([jnp.full((1,), -1, jnp.int32), rank_rest])
    alive_any = jnp.concatenate([alive0.any()[None], alives.any(axis=1)])
    return path, rank, alive_any


def padded_inputs(c: Constraints):
    """The per-frame constraint arrays of the kernels, padded to Tp frames (a multiple of FRAME_BUCKET):
    (reqs, peak_window, peak_reset, peak_check, paper arrays or None). Padding frames constrain nothing."""
    T = c.num_frames
    Tp = max(int(np.ceil(T / FRAME_BUCKET) * FRAME_BUCKET), FRAME_BUCKET)

    def padb(x, v):
        x = np.asarray(x)
        return np.concatenate([x, np.full((Tp - T,) + x.shape[1:], v, x.dtype)])

    reqs = tuple(padb(r, -1) for r in requirement_arrays(c))
    paper_arrs = None
    if c.paper is not None:
        pa = c.paper
        # padding frames: no window, free entries, no flag check
        pad = (-1, 0, 0, 0, True, False, False, 0, 0)   # ... end and peak tolerances (retiming)
        own_a = tuple(padb(a, v) for a, v in zip(pa.own(), pad, strict=True))
        par_a = tuple(padb(a, v) for a, v in zip(pa.partner(), pad, strict=True))
        paper_arrs = (own_a, par_a, (np.int32(pa.own_codes), np.int32(pa.par_codes)), np.int32(c.tol))
    return reqs, padb(c.peak_window, False), padb(c.peak_reset, False), padb(c.peak_check, False), paper_arrs


def lookahead(graph, constraints: Constraints, max_degree: int):
    """(feas (Tp, S_pad) uint8 device array, solvable): the look-ahead of ``search.lookahead``
    (:mod:`convsynth_jax.search.feasible`) over the beam's edge set (each state's ``max_degree``
    cheapest out-edges) and whether any start state can complete the window."""
    prep = _prepare(graph, max_degree)
    feas, ok = feasibility(prep, constraints, padded_inputs(constraints))
    return feas, bool(ok)


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
            res = _beam_search_once(graph, constraints, params, seed, temps[0], None, **kw)
            if not res.success:
                res.failure = (f"{res.failure}; look-ahead: no path of the graph (each state's "
                               f"{int(params.max_degree)} cheapest edges) meets every constraint of the window")
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
    dev = prep.device
    c = constraints
    paper = c.paper is not None
    B, M, N, H = sizes(graph.num_states, beam, prep.max_degree, budget, 4 if paper else 2)
    temp = max(temperature * prep.median_syn, 1e-6)
    T = c.num_frames
    reqs, pw, reset, check, paper_arrs = padded_inputs(c)
    paper_dev = prep.paper_device if paper else None
    prune = feas is not None
    start = start_mask(graph, prep.device[4].shape[0], start_states)
    static = {"beam": B, "M": M, "N": N, "H": H, "D": prep.kernel_degree, "paper": paper}
    args = (prng_key(seed), *dev, reqs, pw, reset, check, np.float32(temp), np.int32(T), np.int32(graph.num_states),
            paper_dev, paper_arrs)
    if lookahead:
        edges = prep.lookahead_edges(None if c.paper is None else (c.paper.own_codes, c.paper.par_codes))
        feas, ok, out = kernel_cache.call(_lookahead_beam_kernel, "lookahead_beam",
                                          (edges, prep.paper_device[1], *args, start), {**static, "F": num_flags(c)})
        res = _result(prep, c, out, t0)
        return res, feas, bool(ok)
    out = kernel_cache.call(_beam_kernel, "beam", (*args, feas if prune else np.zeros((1, 1), np.uint8), start),
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


@partial(jax.jit, static_argnames=("beam", "M", "N", "H", "D", "paper", "F"))
def _lookahead_beam_kernel(edges, info, key, first_edge, flat_packed, flat_cost, deg, state_code, reqs, pw, reset,
                           check, temp, num_frames, num_states, paper_dev, paper_arrs, start, beam: int, M: int,
                           N: int, H: int, D: int, paper: bool, F: int):
    """The look-ahead (``feasible._feasible_kernel``: ``edges`` its :class:`~.feasible.LookaheadEdges`,
    ``info`` the segment info (S, 5)) and the beam pruned by it (:func:`_beam_kernel`) in one program:
    returns (feas, solvable, (path, ranks, alive)). The same computations as the two kernels called
    one after the other (a fresh process loads one compiled program instead of two). ``start``: the
    allowed start states (:func:`_beam_kernel`); solvable then asks for a completable one among them."""
    feas, ok = _feasible_kernel(edges, state_code, info, reqs, pw, reset, check, paper_arrs, num_frames, num_states,
                                F=F, paper=paper)
    out = _beam_kernel(key, first_edge, flat_packed, flat_cost, deg, state_code, reqs, pw, reset, check, temp,
                       num_frames, num_states, paper_dev, paper_arrs, feas, start, beam=beam, M=M, N=N, H=H, D=D,
                       paper=paper, prune=True)
    return feas, ok & out[2][0], out   # out[2][0]: some allowed start state is completable


@partial(jax.jit, static_argnames=("S", "N", "M", "Tp"))
def _noise(key, S: int, N: int, M: int, Tp: int):
    k0, k1, k2 = jax.random.split(key, 3)
    return (jax.random.gumbel(k0, (S,), jnp.float32), jax.random.gumbel(k1, (N,), jnp.float32),
            jax.random.randint(k2, (Tp,), 0, N - M + 1, jnp.int32))


def noise(seed: int, num_states: int, pool_size: int, slots: int, num_frames: int):
    """Gumbel noise of a search: (initial-state noise (S,), pool (N,), per-frame pool offsets (Tp,));
    candidate slot m of frame t draws pool[offsets[t] + m]. Shared by the kernel and the NumPy
    reference so both make the same draws."""
    return _noise(prng_key(seed), num_states, pool_size, slots, num_frames)


def prng_key(seed: int):
    """``jax.random.PRNGKey(seed)``, built on the host for the default threefry keys of seeds in
    0..2**32-1 (their key data is [0, seed]): PRNGKey itself is a small jitted computation whose
    tracing and compilation a fresh process would pay on every search's first call."""
    seed = int(seed)
    if 0 <= seed < 2 ** 32 and jax.config.jax_default_prng_impl == "threefry2x32":
        return np.array([0, seed], np.uint32)
    return jax.random.PRNGKey(seed)
