"""Exact look-ahead for the searches (``search.lookahead``, ours): which (graph state, flags) at
output frame t can still be completed to a path that meets every constraint of the window.

The beam of the paper-matching search dies when none of its paths stands, at the moment an entry
window opens, one transition before a source segment of the right length: the greedy choice cannot
see that a path must wait for a clause start. The constraint rules of both matching modes are a
finite automaton over (graph state, flags) (2 flag values for ``labels``: the peak flag; 4 for
``paper``: the own and partner entry flags), which is why the beam deduplicates on that key. So the
set of completable (state, flags) can be computed exactly by one backward pass over the frames:

    G[T-1] = every (state, flags);
    G[t-1][x, f] = OR over the kept out-edges x -> y (the ``max_degree`` cheapest, as the beam)
                   of  static(x -> y)  and  ok_t(y, f)  and  G[t][y, f'_t(y, f)],

where ok_t / f'_t are the rules of arriving in y at frame t (labels, entry windows, placement,
flag checks; they depend on the target only) and static(x -> y) is the ``paper`` contiguity rule
(a synthetic transition may not leave or enter a constrained source segment in its middle; always
true for ``labels``). The window is solvable by the searches' edge set iff some start state with
its frame-0 flags is in G[0]. A search that keeps only candidates in G never dies on a solvable
window (short of the beam's candidate budget dropping every completable edge of every path).

:func:`feasibility` is the JAX kernel (a reverse ``lax.scan``, per frame a gather over the kept
edges and a segmented OR by cumulative sums); :func:`reference_feasibility` is the slow, obvious
version (Python sets, one edge at a time) the tests compare it with. Both return (T, S) uint8, bit
f of [t, s] set iff (s, f) is in G[t].
"""
from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from .constraints import Constraints, is_peak_state, label_ok, paper_channel_step, requirement_arrays


def num_flags(c: Constraints) -> int:
    """Flag values of the constraint automaton: 4 for ``paper`` (own | partner << 1), 2 for ``labels``."""
    return 4 if c.paper is not None else 2


def leaves_mid(info, own_label, par_label, own_codes, par_codes):
    """(S,) bool: the state lies in a source segment of a constrained kind before its last frame (either
    channel): a synthetic transition may not leave it (``paper`` contiguity). Operators only."""
    cons_o = ((own_codes >> own_label) & 1) == 1
    cons_p = ((par_codes >> par_label) & 1) == 1
    return (cons_o & (info[..., 0] < info[..., 1] - 1)) | (cons_p & (info[..., 3] < info[..., 4] - 1))


def enters_mid(info, own_label, par_label, own_codes, par_codes):
    """(S,) bool: the state lies in a constrained source segment after its first frame: a synthetic
    transition may not enter it (``paper`` contiguity). Operators only."""
    cons_o = ((own_codes >> own_label) & 1) == 1
    cons_p = ((par_codes >> par_label) & 1) == 1
    return (cons_o & (info[..., 0] > 0)) | (cons_p & (info[..., 3] > 0))


SMALL = 4            # states with at most this many kept edges use the narrow table
BIG_BUCKET = 1024    # the wide table's row count is padded to a multiple of this


def edge_tables(adj: np.ndarray, syn: np.ndarray, deg: np.ndarray, pad_state: int):
    """The kept edges of a padded adjacency (``beam.padded_adjacency``, S rows) as two gather tables
    for the look-ahead (a gather and a row sum is much faster than a scatter on CPU): every state's
    first SMALL targets (S, SMALL), and for the states with more edges (rows ``big``) all D of them.
    Missing edges point at ``pad_state`` (a padding state, never completable). Returns
    (small targets, small synthetic, big rows, big targets, big synthetic)."""
    S, D = adj.shape
    rank = np.arange(D)[None, :]
    t = np.where(rank < deg[:, None], adj, pad_state).astype(np.int32)
    y = np.where(rank < deg[:, None], syn, False)
    k = min(SMALL, D)
    big = np.flatnonzero(deg > k).astype(np.int32)
    n = big.size + (-big.size % BIG_BUCKET)
    big_rows = np.full(n, pad_state, np.int32)
    big_rows[:big.size] = big
    big_t = np.full((n, D), pad_state, np.int32)
    big_t[:big.size] = t[big]
    big_y = np.zeros((n, D), bool)
    big_y[:big.size] = y[big]
    return t[:, :k], y[:, :k], big_rows, big_t, big_y


@partial(jax.jit, static_argnames=("F", "paper"))
def _feasible_kernel(edges, state_code, info, reqs, pw, reset, check, paper_arrs, num_frames, F: int, paper: bool):
    """(Tp, S) uint8 bit masks; see the module docstring. The frames from num_frames - 1 on are all ones.
    The OR over a state's kept edges is a sum of per-flag counts packed into the bytes of an int32
    (a state keeps at most 255 edges, so no byte overflows). The last state must be a padding state."""
    from .beam import unpack_code

    small_t, small_y, big, big_t, big_y = edges
    own_y, par_y, peak_y = unpack_code(state_code)
    S = state_code.shape[0]
    two = jnp.array([[False, True]])                                      # a channel's flag values
    no = jnp.zeros((S, 1), bool)
    oy, py, pky, iy = own_y[:, None], par_y[:, None], peak_y[:, None], info[:, None, :]
    if paper:
        own_a, par_a, codes, tol = paper_arrs
        lv = leaves_mid(info, own_y, par_y, codes[0], codes[1])
        en = enters_mid(info, own_y, par_y, codes[0], codes[1])
        # a statically forbidden edge (contiguity) points at the padding state
        small_t = jnp.where(~small_y | ~(lv[:, None] | en[small_t]), small_t, S - 1)
        big_t = jnp.where(~big_y | ~(lv[big][:, None] | en[big_t]), big_t, S - 1)
    fl = jnp.arange(F, dtype=jnp.int32)
    shift = (8 * fl)[None, :]

    def step(G_next, t):
        lab = label_ok(oy, py, tuple(r[t] for r in reqs))                 # (S, 1)
        if paper:
            ok_o, fo = paper_channel_step(oy, iy[..., 0], iy[..., 1], oy, iy[..., 0], iy[..., 1], iy[..., 2], no, no,
                                          t, two, tuple(a[t] for a in own_a), codes[0], tol)     # (S, 2)
            ok_p, fp = paper_channel_step(py, iy[..., 3], iy[..., 4], py, iy[..., 3], iy[..., 4], -1, no, no, t,
                                          two, tuple(a[t] for a in par_a), codes[1], tol)
            ok = lab & ok_o[:, fl & 1] & ok_p[:, fl >> 1]
            f1 = fo[:, fl & 1].astype(jnp.int32) | (fp[:, fl >> 1].astype(jnp.int32) << 1)
        else:
            f1b = (two & ~reset[t]) | (pw[t] & pky)
            ok = lab & (~check[t] | f1b)
            f1 = f1b.astype(jnp.int32)
        A = ok & jnp.take_along_axis(G_next, f1, axis=1)                 # (S, F): arriving at t is completable
        A = A.at[S - 1].set(False)                                        # the padding state of missing edges
        # materialized once per frame: else XLA may fuse the rule into the edge gathers (per edge)
        packed = jax.lax.optimization_barrier((A.astype(jnp.int32) << shift).sum(1))
        cnt = packed[small_t].sum(1).at[big].set(packed[big_t].sum(1))
        G = (((cnt[:, None] >> shift) & 255) > 0) | (t - 1 >= num_frames - 1)
        return G, (G.astype(jnp.int32) << fl[None, :]).sum(1).astype(jnp.uint8)

    Tp = pw.shape[0]
    _, out = jax.lax.scan(step, jnp.ones((S, F), bool), jnp.arange(Tp - 1, 0, -1, dtype=jnp.int32))
    return jnp.concatenate([out[::-1], jnp.full((1, S), (1 << F) - 1, jnp.uint8)])


def feasibility(prep, constraints: Constraints, padded_inputs):
    """(Tp, S_pad) uint8 device array of completable (state, flags) bits (module docstring) for a
    graph prepared by ``beam._prepare``; ``padded_inputs`` = (reqs, pw, reset, check, paper_arrs),
    padded to Tp frames exactly as the beam kernel gets them."""
    c = constraints
    reqs, pw, reset, check, paper_arrs = padded_inputs
    return _feasible_kernel(prep.edges, prep.device[3], prep.paper_device[1], reqs, pw, reset, check, paper_arrs,
                            np.int32(c.num_frames), F=num_flags(c), paper=c.paper is not None)


def solvable(bits0, start_ok, flag0) -> bool:
    """Some start state allowed at frame 0 (``start_ok``) with its flags ``flag0`` is completable."""
    return bool(np.any(start_ok & (((np.asarray(bits0) >> flag0) & 1) == 1)))


def reference_feasibility(graph, constraints: Constraints, max_degree: int) -> np.ndarray:
    """Slow, obvious version of :func:`feasibility`: (T, S) uint8, one state, flag and edge at a time,
    with the reference beam's own rule (:func:`convsynth_jax.search.reference._paper_channel`)."""
    from .reference import _paper_channel, _requirement_ok

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
