"""The beam search's kernels (:mod:`.beam` has the method and the graph preparation): one stochastic
beam over a window (:func:`_beam_kernel`), the look-ahead and the first pruned attempt in one program
(:func:`_lookahead_beam_kernel`), the noise both share with the NumPy reference, and the padded
per-frame inputs as named tuples (:class:`WindowInputs`)."""
from __future__ import annotations

from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .constraints import Constraints, EntryWindows, label_ok, requirement_arrays
from .feasible import _feasible_kernel
from .graph_arrays import CODE_BITS, GraphArrays, PaperGraphArrays
from .rules import paper_step, start_rule, unpack_code

FRAME_BUCKET = 16


class PaperInputs(NamedTuple):
    """``search.matching=paper``: both channels' entry windows, padded to Tp frames."""
    own: EntryWindows        # (Tp,) arrays each
    partner: EntryWindows
    codes: tuple             # (own codes, partner codes): bit masks of the constrained labels
    tol: object              # int32: the tolerance in frames


class WindowInputs(NamedTuple):
    """A window's per-frame constraints as the kernels get them, padded to Tp frames."""
    reqs: tuple              # (own, partner, own_not, partner_not) label requirements, (Tp,) int32 each
    peak_window: object      # (Tp,) bool (labels matching's peak rule)
    peak_reset: object       # (Tp,) bool
    peak_check: object       # (Tp,) bool
    paper: PaperInputs | None


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
def _beam_kernel(key, graph: GraphArrays, inputs: WindowInputs, temp, num_frames, num_states,
                 paper_graph: PaperGraphArrays | None, feas, start, beam: int, M: int, N: int, H: int, D: int,
                 paper: bool = False, prune: bool = False):
    """Returns (path (Tp,), edge rank used into each frame (Tp,), any path alive per frame (Tp,)).
    ``graph``: the flat edges (:class:`~.graph_arrays.GraphArrays`); D is the largest kept degree.
    ``inputs``: the window's per-frame constraints, padded (:func:`padded_inputs`).
    ``paper``: ``paper_graph`` and ``inputs.paper`` hold the entry-window rule; else both unused.
    ``prune``: feas (Tp, S) uint8 is the look-ahead (feasible.py): a candidate (state, flags) at frame
    t is kept only if bit ``flags`` of feas[t, state] is set; else feas is unused. ``start`` (S_pad,) bool:
    the states a path may start from (all True: any state; a chained window: the previous window's
    last state's successors)."""
    B = beam
    # the noise of :func:`noise` (the same jitted draws, inlined: one compilation less per graph)
    first_edge, flat_packed, flat_cost, deg, state_code = graph
    reqs, pw, reset, check, paper_in = inputs
    init_noise, pool, offsets = _noise(key, state_code.shape[0], N, M, pw.shape[0])
    if paper:
        flat_syn, info = paper_graph
        codes, tol = paper_in.codes, paper_in.tol
    valid0, flag0 = start_rule(state_code, info if paper else None, reqs, pw, check, paper_in, num_states, paper)
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
            valid &= ((feas[t, cand] >> f_new.astype(jnp.uint8)) & 1) == 1   # M entries, not a row of S
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
        own_rest, par_rest = tuple(a[1:] for a in paper_in.own), tuple(a[1:] for a in paper_in.partner)
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
    """The per-frame constraint arrays of the kernels (:class:`WindowInputs`), padded to Tp frames (a
    multiple of FRAME_BUCKET). Padding frames constrain nothing."""
    T = c.num_frames
    Tp = max(int(np.ceil(T / FRAME_BUCKET) * FRAME_BUCKET), FRAME_BUCKET)

    def padb(x, v):
        x = np.asarray(x)
        return np.concatenate([x, np.full((Tp - T,) + x.shape[1:], v, x.dtype)])

    reqs = tuple(padb(r, -1) for r in requirement_arrays(c))
    paper_in = None
    if c.paper is not None:
        pa = c.paper
        # padding frames: no window, free entries, no flag check, ... end and peak tolerances (retiming)
        pad = EntryWindows(-1, 0, 0, 0, True, False, False, 0, 0, 0)
        own_a = EntryWindows(*(padb(a, v) for a, v in zip(pa.own(), pad, strict=True)))
        par_a = EntryWindows(*(padb(a, v) for a, v in zip(pa.partner(), pad, strict=True)))
        paper_in = PaperInputs(own_a, par_a, (np.int32(pa.own_codes), np.int32(pa.par_codes)), np.int32(c.tol))
    return WindowInputs(reqs, padb(c.peak_window, False), padb(c.peak_reset, False), padb(c.peak_check, False),
                        paper_in)


@partial(jax.jit, static_argnames=("beam", "M", "N", "H", "D", "paper", "F"))
def _lookahead_beam_kernel(edges, key, graph: GraphArrays, inputs: WindowInputs, temp, num_frames, num_states,
                           paper_graph: PaperGraphArrays, start, beam: int, M: int, N: int, H: int, D: int,
                           paper: bool, F: int):
    """The look-ahead (``feasible._feasible_kernel``: ``edges`` its :class:`~.feasible.LookaheadEdges`;
    it reads the segment info of ``paper_graph``) and the beam pruned by it (:func:`_beam_kernel`) in one program:
    returns (feas, solvable, (path, ranks, alive)). The same computations as the two kernels called
    one after the other (a fresh process loads one compiled program instead of two). ``start``: the
    allowed start states (:func:`_beam_kernel`); solvable then asks for a completable one among them."""
    feas, ok = _feasible_kernel(edges, graph.state_code, paper_graph.segment_info, *inputs, num_frames, num_states,
                                F=F, paper=paper)
    out = _beam_kernel(key, graph, inputs, temp, num_frames, num_states, paper_graph, feas, start, beam=beam, M=M,
                       N=N, H=H, D=D, paper=paper, prune=True)
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
