"""Slow, obvious NumPy reference of the JAX beam search (:mod:`convsynth_jax.search.beam`) and of its look-ahead
(:func:`convsynth_jax.search.feasible.feasibility`).

One frame at a time, one path at a time, one edge at a time, with Python lists and a dict for the
duplicate states. It draws the same noise as the kernel (:func:`convsynth_jax.search.beam.noise`) and
follows the same documented rules, so on graphs whose deduplication table is exact (2 S <= H) it must
return the same path. It shares no code with the kernel beyond the noise and the label rule.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..search.beam import FRAME_BUCKET, noise, padded_states, sizes
from ..search.constraints import NO_PEAK, Constraints, is_peak_state, median_synthetic_cost, requirement_arrays
from ..search.feasible import num_flags
from ..search.params import SearchParams


@dataclass
class ReferenceBeamResult:
    success: bool
    path: np.ndarray | None
    cost: float                 # float32 running sum, as in the kernel
    failed_frame: int | None
    truncated_frames: int       # frames where the candidate budget dropped edges


def _requirement_ok(own, par, req):
    own_r, par_r, own_n, par_n = req
    if own_r >= 0 and own != own_r:
        return False
    if par_r >= 0 and par != par_r:
        return False
    if own_n >= 0 and own == own_n:
        return False
    if par_n >= 0 and par == par_n:
        return False
    return True


def _paper_channel(c, t, frame_arrs, codes, x_seg, y_seg, synthetic, first, flag):
    """``search.matching=paper`` for one channel, written out: x_seg/y_seg = (label, offset, length,
    peak offset) of the previous and the new state. Returns (ok, new flag)."""
    kind, s, e, p, free, reset, check, etol, ptol, stol = (a[t] for a in frame_arrs)
    lx, ox, Lx, _ = x_seg
    ly, oy, Ly, qy = y_seg
    x_cons, y_cons = bool(codes >> int(lx) & 1), bool(codes >> int(ly) & 1)
    if not first and synthetic:
        if x_cons and ox < Lx - 1:      # leaves a source segment before its last frame
            return False, flag
        if y_cons and oy > 0:           # enters a source segment after its first frame
            return False, flag
    if reset:
        flag = False
    if y_cons and (first or oy == 0):   # a source segment is entered here: where does it lie?
        st = t - oy
        # the start slack shifts the whole instance by the start's offset beyond tol: end and peak read after it
        shift = int(st - s) - max(-int(c.tol), min(int(c.tol), int(st - s)))   # the offset beyond tol
        placed = (int(ly) == int(kind) and abs(st - s) <= stol and abs(st - shift + Ly - e) <= etol
                  and (p == NO_PEAK or (qy >= 0 and abs(st - shift + qy - p) <= ptol)))
        if placed and not flag:
            flag = True
        elif not free:
            return False, flag
    if check and not flag:
        return False, flag
    return True, flag


def reference_beam_search(graph, constraints: Constraints, params: SearchParams, seed: int = 0,
                          temperature: float | None = None, feas: np.ndarray | None = None) -> ReferenceBeamResult:
    """One attempt at ``temperature`` (default ``search.temperature``), as ``beam._beam_search_once``;
    with ``search.lookahead`` as ``beam.beam_search`` does it: candidates outside the look-ahead
    (:func:`reference_feasibility`) are dropped, and an unsolvable
    window gets one attempt without it. ``feas``: that look-ahead when the caller already computed it
    with :func:`reference_feasibility` for this graph, these constraints and ``search.max_degree``
    (it does not depend on the beam's sizes or temperature, so tests share it across them)."""
    if temperature is None:
        temperature = float(params.temperature)
    if not params.lookahead:
        feas = None
    elif feas is None:
        feas = reference_feasibility(graph, constraints, int(params.max_degree))
    return _reference_once(graph, constraints, params, seed, temperature, feas)


def _flag_bits(flag) -> int:
    return int(flag[0]) | (int(flag[1]) << 1) if isinstance(flag, tuple) else int(flag)


def _reference_once(graph, constraints, params, seed, temperature, feas) -> ReferenceBeamResult:
    max_deg = int(params.max_degree)
    S = graph.num_states
    # each state's edges, cheapest first (ties: CSR order), at most D of them
    edges = []
    for s in range(S):
        t, c, _ = graph.out_edges(s)
        o = sorted(range(len(t)), key=lambda k: (float(c[k]), k))
        edges.append([(int(t[k]), np.float32(c[k])) for k in o])
    D = max(1, min(max(len(e) for e in edges), max_deg))
    edges = [e[:D] for e in edges]
    c = constraints
    paper = c.paper is not None
    keys = 4 if paper else 2
    B, M, N, H = sizes(S, int(params.beam_size), D, int(params.max_candidates), keys)
    if keys * S > H:
        raise ValueError(f"the reference deduplicates exactly; the kernel's table ({H} slots) is only exact "
                         f"for graphs of at most {H // keys} states, this one has {S}")
    syn_of = {}
    for s_ in range(S):
        t_, c_, y_ = graph.out_edges(s_)
        for k in range(len(t_)):
            syn_of.setdefault((s_, int(t_[k])), bool(y_[k]))

    def seg(s_, channel):
        if channel == "own":
            on = own_l[s_] != 0 and graph.own_start[s_] >= 0
            if not on:
                return (int(own_l[s_]), -1, 0, -1)
            a = int(graph.own_start[s_])
            q = int(graph.own_peak[s_]) - a if graph.own_peak[s_] >= 0 else -1
            return (int(own_l[s_]), int(graph.frame[s_]) - a, int(graph.own_end[s_]) - a, q)
        on = par_l[s_] != 0 and graph.partner_start[s_] >= 0
        if not on:
            return (int(par_l[s_]), -1, 0, -1)
        a = int(graph.partner_start[s_])
        return (int(par_l[s_]), int(graph.frame[s_]) - a, int(graph.partner_end[s_]) - a, -1)

    def paper_step(t, x, y, flags, first):
        """(ok, flags) of both channels; flags = (own, partner)."""
        syn = False if first else syn_of[(x, y)]
        ok_o, fo = _paper_channel(c, t, c.paper.own(), c.paper.own_codes, seg(x, "own"), seg(y, "own"), syn,
                                  first, flags[0])
        ok_p, fp = _paper_channel(c, t, c.paper.partner(), c.paper.par_codes, seg(x, "par"), seg(y, "par"), syn,
                                  first, flags[1])
        return ok_o and ok_p, (fo, fp)
    temp = np.float32(max(temperature * median_synthetic_cost(graph), 1e-6))
    T = constraints.num_frames
    Tp = max(int(np.ceil(T / FRAME_BUCKET) * FRAME_BUCKET), FRAME_BUCKET)
    S_pad = padded_states(S)
    init_noise, pool, offsets = (np.asarray(x) for x in noise(seed, S_pad, N, M, Tp))
    own_l, par_l = np.asarray(graph.own_label), np.asarray(graph.partner_label)
    peak = is_peak_state(graph)
    req_arrays = requirement_arrays(c)

    def req(t):
        return tuple(int(a[t]) for a in req_arrays)

    # frame 0: the B valid states with the largest noise, in descending order (ties: lower state first)
    if paper:
        first = [paper_step(0, s, s, (False, False), True) for s in range(S)]
        flag0 = [f for _, f in first]
        valid0 = [s for s in range(S) if _requirement_ok(own_l[s], par_l[s], req(0)) and first[s][0]]
    else:
        flag0 = [bool(c.peak_window[0] and peak[s]) for s in range(S)]
        valid0 = [s for s in range(S) if _requirement_ok(own_l[s], par_l[s], req(0))
                  and (not c.peak_check[0] or flag0[s])]
    if feas is not None:
        kept0 = [s for s in valid0 if feas[0, s] >> _flag_bits(flag0[s]) & 1]
        if not kept0:   # unsolvable: the attempt without the look-ahead names where the paths die
            return _reference_once(graph, constraints, params, seed, temperature, None)
        valid0 = kept0
    valid0.sort(key=lambda s: (-float(init_noise[s]), s))
    # beam entries: (state, cost, flag, index of the parent entry in the previous frame's beam)
    beam = [(s, np.float32(0.0), flag0[s], -1) for s in valid0[:B]]
    history = [beam]
    truncated = 0
    for t in range(1, T):
        if not beam:
            return ReferenceBeamResult(False, None, float("inf"), t - 1, truncated)
        degrees = [len(edges[s]) for s, *_ in beam]
        rstar = max(k for k in range(D + 1) if sum(min(d, k) for d in degrees) <= M)
        truncated += rstar < max(degrees)
        cands = []     # (score, slot, state, cost, flag, parent)
        slot = 0
        for b, (s, cost, flag, _) in enumerate(beam):
            for target, ec in edges[s][:min(degrees[b], rstar)]:
                cc = np.float32(cost + ec)
                if paper:
                    ok, f = paper_step(t, s, target, flag, False)
                    ok = ok and _requirement_ok(own_l[target], par_l[target], req(t))
                else:
                    f = (False if c.peak_reset[t] else flag) or bool(c.peak_window[t] and peak[target])
                    ok = _requirement_ok(own_l[target], par_l[target], req(t)) and (f or not c.peak_check[t])
                score = np.float32(np.float32(-cc) / temp) + np.float32(pool[offsets[t] + slot])
                if ok and feas is not None:
                    ok = bool(feas[t, target] >> _flag_bits(f) & 1)
                if ok:
                    cands.append((float(score), slot, target, cc, f, b))
                slot += 1
        best = {}
        for cand in cands:
            key = (cand[2], cand[4])
            if key not in best or cand[0] > best[key][0]:
                best[key] = cand
        kept = sorted(best.values(), key=lambda x: (-x[0], x[1]))[:B]
        beam = [(st, cc, f, b) for _, _, st, cc, f, b in kept]
        history.append(beam)
    if not beam:
        return ReferenceBeamResult(False, None, float("inf"), T - 1, truncated)
    b = min(range(len(beam)), key=lambda i: (float(beam[i][1]), i))
    final_cost = float(beam[b][1])
    path = np.empty(T, np.int64)
    for t in range(T - 1, -1, -1):
        s, _, _, parent = history[t][b]
        path[t] = s
        b = parent
    return ReferenceBeamResult(True, path, final_cost, None, truncated)


def reference_feasibility(graph, constraints: Constraints, max_degree: int) -> np.ndarray:
    """Slow, obvious version of :func:`feasibility`: (T, S) uint8, one state, flag and edge at a time,
    with the reference beam's own rule (:func:`_paper_channel`)."""
    c = constraints
    S, T = graph.num_states, c.num_frames
    paper = c.paper is not None
    F = num_flags(c)
    edges = []
    for s in range(S):
        t_, c_, y_ = graph.out_edges(s)
        o = sorted(range(len(t_)), key=lambda k: (float(c_[k]), k))
        edges.append([(int(t_[k]), bool(y_[k])) for k in o])
    D = max(1, min(max(len(e) for e in edges), max_degree))
    edges = [e[:D] for e in edges]
    own_l, par_l = np.asarray(graph.own_label), np.asarray(graph.partner_label)
    peak = is_peak_state(graph)
    req_arrays = requirement_arrays(c)

    def seg(s_, channel):
        if channel == "own":
            if not (own_l[s_] != 0 and graph.own_start[s_] >= 0):
                return (int(own_l[s_]), -1, 0, -1)
            a = int(graph.own_start[s_])
            q = int(graph.own_peak[s_]) - a if graph.own_peak[s_] >= 0 else -1
            return (int(own_l[s_]), int(graph.frame[s_]) - a, int(graph.own_end[s_]) - a, q)
        if not (par_l[s_] != 0 and graph.partner_start[s_] >= 0):
            return (int(par_l[s_]), -1, 0, -1)
        a = int(graph.partner_start[s_])
        return (int(par_l[s_]), int(graph.frame[s_]) - a, int(graph.partner_end[s_]) - a, -1)

    def arrive(t, x, y, syn, f):
        """(ok, new flag) of the edge x -> y arriving at frame t with flag f."""
        if not _requirement_ok(own_l[y], par_l[y], tuple(int(a[t]) for a in req_arrays)):
            return False, f
        if not paper:
            f2 = (False if c.peak_reset[t] else bool(f)) or bool(c.peak_window[t] and peak[y])
            return (f2 or not c.peak_check[t]), int(f2)
        ok_o, fo = _paper_channel(c, t, c.paper.own(), c.paper.own_codes, seg(x, "own"), seg(y, "own"), syn, False,
                                  bool(f & 1))
        ok_p, fp = _paper_channel(c, t, c.paper.partner(), c.paper.par_codes, seg(x, "par"), seg(y, "par"), syn,
                                  False, bool(f & 2))
        return ok_o and ok_p, int(fo) | (int(fp) << 1)

    out = np.zeros((T, S), np.uint8)
    good = {(s, f) for s in range(S) for f in range(F)}
    out[T - 1] = (1 << F) - 1
    for t in range(T - 1, 0, -1):
        prev = set()
        for x in range(S):
            for f in range(F):
                for y, syn in edges[x]:
                    ok, f2 = arrive(t, x, y, syn, f)
                    if ok and (y, f2) in good:
                        prev.add((x, f))
                        break
        good = prev
        for x, f in good:
            out[t - 1, x] |= 1 << f
    return out
