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

:func:`feasibility` is the JAX kernel (a reverse ``lax.scan`` over bytes of F bits per state; per
frame the arrival rule, computed per state only where it depends on the state, and the OR over the
kept edges as a shift for the original transitions plus a bitwise OR over the others, gathered as
dense rows per source state (:func:`edge_or`),
the statically forbidden ones dropped on the host: :class:`LookaheadEdges`), or, on big graphs
(``search.lookahead_pass``), frame to frame over the states whose bits changed and their in-edges
only (the same bits; :func:`_feasible_kernel`, docs/scale.md);
:func:`reference_feasibility` is the slow, obvious version (Python sets, one edge at a time) the
tests compare it with. Both return (T, S) uint8, bit f of [t, s] set iff (s, f) is in G[t].
"""
from __future__ import annotations

import dataclasses
from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .. import kernel_cache
from ..errors import ConfigError
from .constraints import Constraints, EntryWindows, label_ok, paper_channel_step
from .rules import start_rule, unpack_code


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


ROW_BUCKET = 256      # the rows of each width are padded to a multiple of this (compiles shared across folds)
ENTRY_BUCKET = 1024   # the entry-state list is padded to a multiple of this
MIN_WIDTH = 4         # the narrowest row; widths double up to the largest kept degree


def row_widths(max_degree: int) -> tuple:
    """The row widths of :class:`LookaheadEdges`: 4, 8, ... up to the first >= ``max_degree``."""
    w = [MIN_WIDTH]
    while w[-1] < max_degree:
        w.append(2 * w[-1])
    return tuple(w)


class LookaheadEdges(NamedTuple):
    """The kept edges (``beam.kept_edges``) in the look-ahead's layout.

    An original transition x -> x + 1 (every state but a clip's last has one, always its cheapest)
    is a flag ``has_next`` (S,): its OR term is a shifted copy of the next frame's bits, no gather.
    Every other kept edge, minus the ones the ``paper`` contiguity rule always forbids (a synthetic
    transition leaving a constrained source segment before its last frame or entering one after its
    first: static, so dropped on the host), sits in a dense row of its source state: the states with
    such edges are grouped by count into widths 4, 8, 16, ... (:func:`row_widths`), ``src[k]`` (n_k,)
    lists the states of width k and ``tgt[k]`` (n_k, w_k) their targets, padded with the padding
    state (no bits), rows padded with rows of the padding state. A gather and a reduction along the
    rows is about twice as fast on the CPU as the scatter-add over a flat list used before.
    ``entry`` (n,) lists the states at the first frame of a source segment of a kind the window
    constrains (own or partner offset 0, label in the window's codes; for ``labels``, where it is
    unused, every segment start), padded with the padding state: only there do the ``paper`` entry
    rules depend on the state; elsewhere the arrival rule of a frame is the same for every state
    (module docstring of :func:`_feasible_kernel`)."""

    has_next: np.ndarray    # (S,) bool
    src: tuple              # per width: (n_k,) int32 source states
    tgt: tuple              # per width: (n_k, w_k) int32 targets
    entry: np.ndarray       # (n,) int32
    sparse: SparseEdges | None = None   # the changed-state look-ahead's lists (None: the dense pass only)


@partial(jax.tree_util.register_dataclass, data_fields=["in_ptr", "in_src", "is_entry"], meta_fields=["capacity"])
@dataclasses.dataclass(frozen=True)
class SparseEdges:
    """The listed edges of :class:`LookaheadEdges` (the rows, not the original transitions) by
    destination, for the changed-state look-ahead (:func:`_feasible_kernel` with ``sparse``): the
    sources whose edge counts change when a target's arrival byte does. ``is_entry`` (S,) bool marks
    the entry states (their arrival byte is recomputed every frame). ``capacity`` (static): the sizes
    of its per-frame buffers (:class:`SparseCapacity`); a frame whose changes do not fit takes the
    dense pass."""

    in_ptr: np.ndarray      # (S + 1,) int32: state y's listed sources are in_src[in_ptr[y] : in_ptr[y + 1]]
    in_src: np.ndarray      # (E,) int32 (padded: entries past in_ptr[S] are never read)
    is_entry: np.ndarray    # (S,) bool
    capacity: SparseCapacity


class SparseCapacity(NamedTuple):
    """Buffer sizes of the changed-state look-ahead (static). ``sources``: the most in-edge entries
    (listed in-edges and original transitions) of the states whose arrival byte changes that one frame
    may follow; a frame with more takes the dense pass. Its work is done in chunks of ``chunk``
    entries, as many as it needs, so it follows the number of changes, not the buffer's size."""
    sources: int
    chunk: int = 2048


SPARSE_MIN_STATES = 1 << 17   # graphs of fewer (padded) states take the dense pass only under "auto"
SPARSE_FRACTION = 32          # "auto": a frame with more than S / 32 in-edge entries to follow takes the dense pass


def sparse_capacity(num_states: int) -> SparseCapacity | None:
    """The default buffer sizes for a graph of ``num_states`` padded states: None (dense only) below
    SPARSE_MIN_STATES, else S / SPARSE_FRACTION in-edge entries per frame (a median of about 0.6% of
    the states change per frame on the 1M-frame graph, docs/scale.md)."""
    if num_states < SPARSE_MIN_STATES:
        return None
    return SparseCapacity(num_states // SPARSE_FRACTION)


LOOKAHEAD_PASSES = ("auto", "changed", "dense")


def lookahead_capacity(mode: str, num_states: int) -> SparseCapacity | None:
    """The changed-state buffers of ``search.lookahead_pass`` = ``mode`` on a graph of ``num_states``
    padded states (None: the dense pass)."""
    if mode not in LOOKAHEAD_PASSES:
        raise ConfigError(f"search.lookahead_pass must be one of {', '.join(LOOKAHEAD_PASSES)}, got {mode!r}")
    if mode == "dense":
        return None
    if mode == "changed":
        return SparseCapacity(max(num_states // SPARSE_FRACTION, 1))
    return sparse_capacity(num_states)


def sparse_edges(src: np.ndarray, dst: np.ndarray, entry: np.ndarray, num_states: int,
                 capacity: SparseCapacity) -> SparseEdges:
    """:class:`SparseEdges` of the listed edges src -> dst over ``num_states`` states with the entry
    states ``entry`` (padding entries point at the last state). Host NumPy."""
    src = np.asarray(src, np.int64)
    dst = np.asarray(dst, np.int64)
    if src.size and np.bincount(src).max() >= 256:
        raise ValueError("a state has 256 or more listed edges: the changed-state look-ahead counts them in bytes")
    o = np.argsort(dst, kind="stable")
    in_ptr = np.concatenate([[0], np.cumsum(np.bincount(dst, minlength=num_states))]).astype(np.int32)
    n = max(src.size + (-src.size % ROW_BUCKET), ROW_BUCKET)
    in_src = np.zeros(n, np.int32)
    in_src[:src.size] = src[o]
    is_entry = np.zeros(num_states, bool)
    is_entry[np.asarray(entry)] = True
    is_entry[num_states - 1] = False
    cap = SparseCapacity(*map(int, capacity))
    if min(cap) < 1:
        raise ValueError(f"changed-state look-ahead buffers must be >= 1, got {cap}")
    cap = cap._replace(sources=cap.sources + (-cap.sources % cap.chunk))    # whole chunks
    return SparseEdges(in_ptr, in_src, is_entry, cap)


def edge_rows(src: np.ndarray, dst: np.ndarray, pad_state: int, widths: tuple):
    """(src rows per width, target rows per width) of :class:`LookaheadEdges` from flat edge lists
    sorted by source. Host NumPy."""
    src = np.asarray(src, np.int64)
    dst = np.asarray(dst, np.int64)
    states, first, counts = np.unique(src, return_index=True, return_counts=True)
    if counts.size and counts.max() > widths[-1]:
        raise ValueError(f"a state has {counts.max()} listed edges, more than the widest row ({widths[-1]})")
    kind = np.searchsorted(np.asarray(widths), counts)            # the narrowest width that holds the state
    rank = np.arange(src.size) - np.repeat(first, counts)        # an edge's position in its state's row
    state_of_edge = np.repeat(np.arange(states.size), counts)
    s_rows, t_rows = [], []
    for k, w in enumerate(widths):
        sel = np.flatnonzero(kind == k)
        n = sel.size + (-sel.size % ROW_BUCKET)
        srow = np.full(n, pad_state, np.int32)
        trow = np.full((n, w), pad_state, np.int32)
        srow[:sel.size] = states[sel]
        row_of = np.full(states.size, -1, np.int64)
        row_of[sel] = np.arange(sel.size)
        e = np.flatnonzero(kind[state_of_edge] == k)
        trow[row_of[state_of_edge[e]], rank[e]] = dst[e]
        s_rows.append(srow)
        t_rows.append(trow)
    return tuple(s_rows), tuple(t_rows)


def lookahead_edges(first: np.ndarray, deg: np.ndarray, tgt: np.ndarray, syn: np.ndarray, info: np.ndarray,
                    state_code: np.ndarray, num_states: int, codes=None,
                    max_degree: int | None = None, capacity="auto") -> LookaheadEdges:
    """:class:`LookaheadEdges` of the kept edges in the beam's flat layout (``beam.kept_edges``: state
    s's edges are tgt/syn[first[s] : first[s] + deg[s]]), for S states of which those from
    ``num_states`` on are padding (the last one, S - 1, is where padded entries point). ``info``:
    (S, 5) ``constraints.segment_info``; ``state_code`` (S,) ``beam.state_codes``; ``codes``: (own
    codes, partner codes) of a ``paper`` window (its static contiguity rule is applied), None for
    ``labels`` (every kept edge stays). ``max_degree``: the widest row (default: the largest degree).
    Host NumPy."""
    S = first.shape[0]
    pad_state = S - 1
    row = np.repeat(np.arange(S, dtype=np.int32), deg)               # kept edges are stored state after state
    nxt = ~syn & (tgt == row + 1)
    rest = ~nxt
    if codes is not None:
        own_label, par_label = state_code & 15, (state_code >> 4) & 15
        lv = leaves_mid(info, own_label, par_label, int(codes[0]), int(codes[1]))
        en = enters_mid(info, own_label, par_label, int(codes[0]), int(codes[1]))
        rest &= ~(syn & (lv[row] | en[tgt]))
    src, dst = row[rest], tgt[rest]                                   # sorted by source
    has_next = np.zeros(S, bool)
    has_next[row[nxt]] = True
    widths = row_widths(int(max_degree) if max_degree else int(deg.max(initial=1)))
    s_rows, t_rows = edge_rows(src, dst, pad_state, widths)
    if codes is None:
        ent = np.flatnonzero((info[:num_states, 0] == 0) | (info[:num_states, 3] == 0))
    else:   # elsewhere the channel rule is the common one (no entry: paper_channel_step's entry is False)
        own_label, par_label = state_code[:num_states] & 15, (state_code[:num_states] >> 4) & 15
        cons_o = ((int(codes[0]) >> own_label) & 1) == 1
        cons_p = ((int(codes[1]) >> par_label) & 1) == 1
        ent = np.flatnonzero((cons_o & (info[:num_states, 0] == 0)) | (cons_p & (info[:num_states, 3] == 0)))
    m = ent.size + (-ent.size % ENTRY_BUCKET) if ent.size else ENTRY_BUCKET
    ent_p = np.full(m, pad_state, np.int32)
    ent_p[:ent.size] = ent
    if isinstance(capacity, str):
        capacity = sparse_capacity(S)
    sparse = None if capacity is None else sparse_edges(src, dst, ent_p, S, capacity)
    return LookaheadEdges(has_next, s_rows, t_rows, ent_p, sparse)


def pad_lookahead(e: LookaheadEdges, min_rows, min_entries: int, min_edges: int | None = None) -> LookaheadEdges:
    """``e`` with each width's rows and the entry list padded (with the padding state, the last one)
    to at least ``min_rows[k]`` / ``min_entries``, and the flat lists of its :class:`SparseEdges` to
    ``min_edges`` entries: the lists of graphs that share one compiled kernel
    (``beam.share_shapes``), without building them again. Host NumPy."""
    pad_state = e.has_next.shape[0] - 1

    def grow(x, n):
        extra = max(int(n) - x.shape[0], 0)
        return np.concatenate([x, np.full((extra,) + x.shape[1:], pad_state, x.dtype)]) if extra else x

    sp = e.sparse
    if sp is not None and min_edges is not None:
        sp = dataclasses.replace(sp, in_src=grow(sp.in_src, min_edges))
    return LookaheadEdges(e.has_next, tuple(grow(x, n) for x, n in zip(e.src, min_rows)),
                          tuple(grow(x, n) for x, n in zip(e.tgt, min_rows)), grow(e.entry, min_entries), sp)


def edge_or(A, src, tgt, S: int):
    """Bitwise OR of the bytes A[y] over each state's listed edges x -> y: (S,) uint8, 0 for states
    without listed edges. ``src`` / ``tgt``: the rows of :class:`LookaheadEdges` (per width (n_k,)
    states and (n_k, w_k) targets; padding rows and entries point at a state whose byte is 0)."""
    out = jnp.zeros(S, jnp.uint8)
    for s_k, t_k in zip(src, tgt):
        r = jax.lax.reduce(A[t_k], np.uint8(0), jax.lax.bitwise_or, (1,))
        out = out.at[s_k].set(r, indices_are_sorted=True)
    return out


def same_rule(reqs, pw, reset, check, paper_arrs, paper: bool):
    """(Tp,) bool: the arrival rule of frame u is the rule of frame u + 1 (False at the last frame): every
    per-frame input equal, and for ``paper`` no entry window open on either channel at u (inside one the
    placement check depends on u itself). Operators only."""
    fields = [*reqs, pw, reset, check]
    no_window = jnp.ones(pw.shape[0], bool)
    if paper:
        own_a, par_a = paper_arrs[0], paper_arrs[1]
        fields += [*own_a, *par_a]
        no_window = (own_a.kind < 0) & (par_a.kind < 0)
    same = no_window[:-1]
    for a in fields:
        same &= a[:-1] == a[1:]
    return jnp.concatenate([same, jnp.zeros(1, bool)])


def _expand(counts, cap: int):
    """Slots 0..cap-1 over items with ``counts`` (n,) entries each, item after item: (item of each slot,
    rank of the slot within its item, slot in use, total count). Operators only (no sort)."""
    offs = jnp.cumsum(counts) - counts
    total = jnp.sum(counts)
    slots = jnp.arange(cap, dtype=jnp.int32)
    item = jax.lax.cummax(jnp.full(cap, -1, jnp.int32).at[offs].max(jnp.arange(counts.shape[0], dtype=jnp.int32),
                                                                     mode="drop"))
    item = jnp.maximum(item, 0)
    return item, slots - offs[item], slots < total, total


def _compact(values, keep, cap: int, fill: int):
    """(the ``values`` where ``keep``, in order, in a (cap,) buffer padded with ``fill``; their count)."""
    pos = jnp.where(keep, jnp.cumsum(keep) - 1, cap)
    return jnp.full(cap, fill, values.dtype).at[pos].set(values, mode="drop"), jnp.sum(keep, dtype=jnp.int32)


@partial(jax.jit, static_argnames=("F", "paper", "stats"))
def _feasible_kernel(edges, state_code, info, reqs, pw, reset, check, paper_arrs, num_frames, num_states, F: int,
                     paper: bool, stats: bool = False):
    """((Tp, S) uint8 bit masks, solvable); see the module docstring. ``stats``: also return per frame
    (how it was computed (Tp,) int32: -1 padding, 0 dense pass, 1 changed states, 2 fixed point;
    the number of states whose byte changed (Tp,) int32), for the benchmarks. The frames from num_frames - 1 on
    are all ones; solvable: some start state (``rules.start_rule``) with its frame-0 flags is completable.
    ``edges``: :class:`LookaheadEdges` (device arrays; for ``paper`` built with the window's codes).
    The last state must be a padding state.

    Per frame t, with G[t] as one byte of F bits per state:

    * arriving in y at frame t with flags f is completable, A[y, f] = label_ok_t(y) and ok_t(y, f) and
      G[t][y, f'_t(y, f)]. For ``labels`` ok/f' depend on y only through its peak flag.
      For ``paper`` they depend on y only where y enters a source segment (offset 0: the ``entry``
      states); for every other state the channel rule is the frame's: f' = f and not reset, ok = not
      check or f'. So A is computed for all states with that rule and recomputed with
      ``paper_channel_step`` for the entry states only. That rule depends on a state only through
      the low 9 bits of its code (labels, peak) and its byte G[t][y]: per frame it is tabulated for
      the 512 x 2^F combinations and looked up per state (one gather from a small table instead of
      a dozen elementwise passes over S);
    * G[t-1][x] = A[x + 1] where x has its original transition (a shift), OR the bitwise OR of the
      bytes A[y] over x's other edges (:func:`edge_or` over the dense rows);
    * fixed points: when frame t's rule is frame t + 1's (:func:`same_rule`: the same per-frame inputs,
      no entry window open) and G[t] came out equal to G[t + 1], then G[t - 1] = G[t] without a pass
      over the graph (a rule applied to its own fixed point gives it back). Unconstrained stretches of
      a window cost one comparison per frame once their bits settle; the bits are unchanged.

    Changed states (``edges.sparse`` set: :class:`SparseEdges`): instead of the OR, each state carries
    its edge counts, per flag bit how many of its listed out-edges arrive in a state with that bit set
    in A (one byte lane per bit, :func:`edge_lane_counts`); G[t-1][x] is the set of nonzero lanes
    (plus the shift). When frame t's table of the common rule equals frame t + 1's, A[t] differs from
    A[t + 1] only at the states whose byte G changed between the two frames (looked up anew) and at
    entry states (their full rule, recomputed where the rule does not repeat or one of their bytes
    changed). Each changed A[y] adds its lane differences to the counts of its in-edge sources (CSR
    by destination) and y - 1 (original transition); only those sources are recomputed, and the ones
    whose byte changed are carried to the next frame. A frame without changes whose rule repeats
    (:func:`same_rule`) does nothing. The work of a frame is done in chunks of ``capacity.chunk``
    entries in while loops (as many as its changes need; the full-size arrays are updated in place,
    never copied); a frame whose table changes or that follows more than ``capacity.sources``
    in-edge entries takes the dense pass (with counts), which also lists its changed states for the
    next frame. Both give the same bytes. The frames run as nested while loops, backwards: a dense
    frame, then changed-state frames while they may; each frame's row is written in place into the
    (Tp, S) table, initialized to all ones (the padding frames).

    The dense pass (``edges.sparse`` None) is a reverse ``lax.scan``, so each frame's row lands in
    place in the (Tp, S) table."""

    has_next, src, tgt, entry, sparse = edges
    own_y, par_y, peak_y = unpack_code(state_code)
    S = state_code.shape[0]
    u8 = jnp.uint8
    last = S - 1
    fl = jnp.arange(F, dtype=jnp.int32)
    if paper:
        own_a, par_a, codes, tol = paper_arrs
        own_e, par_e, info_e = own_y[entry][:, None], par_y[entry][:, None], info[entry][:, None, :]
        two = jnp.array([[False, True]])                                  # a channel's flag values
        no = jnp.zeros((entry.shape[0], 1), bool)
    all_ones = u8((1 << F) - 1)
    Tp = pw.shape[0]
    # the rule of a non-entry state depends on its code's low 9 bits (labels, peak) and its byte G[t] only:
    # per frame a (512, 2^F) table of it, looked up per state (cheaper than the rule's passes over S)
    c_own, c_par, c_peak = unpack_code(jnp.arange(512, dtype=jnp.int32)[:, None])
    c_g = jnp.arange(1 << F, dtype=jnp.int32)[None, :].astype(u8)
    lut_index = (state_code & 511) << F
    same_op = same_rule(reqs, pw, reset, check, paper_arrs, paper)

    def frame_table(t):
        """The common arrival rule of frame t as a (512 * 2^F,) table: code's low 9 bits << F | G[t][y]."""
        req_t = tuple(r[t] for r in reqs)
        if paper:
            oa, pa = EntryWindows(*(a[t] for a in own_a)), EntryWindows(*(a[t] for a in par_a))

        def plain(own, par, peak, G):   # the rule of a state that enters no source segment (broadcasts)
            A = jnp.zeros(jnp.broadcast_shapes(own.shape, G.shape), u8)
            if paper:
                fo = (fl & 1).astype(bool) & ~oa.reset                   # flags after the frame's resets
                fp = (fl >> 1).astype(bool) & ~pa.reset
                ok = (~oa.check | fo) & (~pa.check | fp)                  # (F,): the flag checks
                f1 = fo.astype(jnp.int32) | (fp.astype(jnp.int32) << 1)
                for f in range(F):
                    A |= (ok[f] & (((G >> f1[f].astype(u8)) & 1) == 1)).astype(u8) << f
            else:
                for f in range(F):
                    g1 = (bool(f) & ~reset[t]) | (pw[t] & peak)
                    okf = (~check[t] | g1) & (((G >> g1.astype(u8)) & 1) == 1)
                    A |= okf.astype(u8) << f
            return jnp.where(label_ok(own, par, req_t), A, u8(0))

        return plain(c_own, c_par, c_peak, c_g).reshape(-1)

    def entry_rule(G_next, t):
        """(n,) the arrival bytes of the entry states at frame t (``paper``: the full rule,
        constraints.paper_channel_step)."""
        req_t = tuple(r[t] for r in reqs)
        oa, pa = EntryWindows(*(a[t] for a in own_a)), EntryWindows(*(a[t] for a in par_a))
        Ge = G_next[entry]
        ok_o, go = paper_channel_step(own_e, info_e[..., 0], info_e[..., 1], own_e, info_e[..., 0],
                                      info_e[..., 1], info_e[..., 2], no, no, t, two, oa, codes[0], tol)  # (n, 2)
        ok_p, gp = paper_channel_step(par_e, info_e[..., 3], info_e[..., 4], par_e, info_e[..., 3],
                                      info_e[..., 4], -1, no, no, t, two, pa, codes[1], tol)
        Ae = jnp.zeros(entry.shape[0], u8)
        for f in range(F):
            g1 = go[:, f & 1].astype(u8) | (gp[:, f >> 1].astype(u8) << 1)
            okf = ok_o[:, f & 1] & ok_p[:, f >> 1] & (((Ge >> g1) & 1) == 1)
            Ae |= okf.astype(u8) << f
        return jnp.where(label_ok(own_e[:, 0], par_e[:, 0], req_t), Ae, u8(0))

    def arrival(G_next, t, table):
        """(S,) the arrival bytes A of frame t from G[t] = G_next, by the frame's table and entry rule."""
        A = table[lut_index | G_next.astype(jnp.int32)]
        if paper:   # the entry states: the full rule, gathered and scattered back
            A = A.at[entry].set(entry_rule(G_next, t))
        return A.at[last].set(0)                                          # the padding state of missing edges

    def propagate(A):
        """G[t - 1] of the arrival bytes A of frame t: the shift and the OR over the dense rows."""
        # materialized once per frame: else XLA may fuse the rule into the edge gathers (per edge)
        A = jax.lax.optimization_barrier(A)
        G = edge_or(A, src, tgt, S)
        return G | jnp.where(has_next, jnp.concatenate([A[1:], jnp.zeros(1, u8)]), u8(0))

    valid0, flag0 = start_rule(state_code, info, reqs, pw, check, paper_arrs, num_states, paper)

    if sparse is None:
        def step(carry, t):
            G_next, still = carry     # G[t + 1]; still: G[t + 1] == G[t + 2], computed by frame t + 2's rule
            u = jnp.minimum(t + 1, Tp - 1)                                # the arrival frame
            pad = t >= num_frames - 1
            # a rule applied to its own fixed point gives it back: no pass over the graph
            skip = pad | (still & same_op[u])
            G = jax.lax.cond(skip, lambda g: jnp.where(pad, all_ones, g),
                             lambda g: propagate(arrival(g, u, frame_table(u))), G_next)
            out = G
            if stats:
                out = (G, jnp.where(pad, -1, jnp.where(skip, 2, 0)), jnp.sum(G != G_next, dtype=jnp.int32))
            return (G, ~pad & (skip | jnp.all(G == G_next))), out

        # reverse=True: frame t's row is written at t (no reversed copy of the (Tp, S) table)
        _, feas = jax.lax.scan(step, (jnp.full(S, all_ones), jnp.bool_(False)), jnp.arange(Tp, dtype=jnp.int32),
                               reverse=True)
        if stats:
            feas, info_out = feas[0], feas[1:]
        ok = jnp.any(valid0 & (((feas[0] >> flag0.astype(u8)) & 1) == 1))
        return (feas, ok, info_out) if stats else (feas, ok)

    cap = sparse.capacity
    KX, CH = cap.sources, cap.chunk
    KB = KX + CH                                                          # the changed arrivals' buffers
    tables = jax.vmap(frame_table)(jnp.arange(Tp, dtype=jnp.int32))       # (Tp, 512 * 2^F)
    same_table = jnp.concatenate([jnp.all(tables[:-1] == tables[1:], axis=1), jnp.zeros(1, bool)])
    lanes_of = jnp.asarray(byte_lanes(F))                                 # byte -> one byte lane per flag bit
    hn_prev = jnp.concatenate([jnp.zeros(1, bool), has_next[:-1]])        # y - 1 reaches y by its original transition
    in_ptr, in_src, is_entry = sparse.in_ptr, sparse.in_src, sparse.is_entry
    in_deg = jnp.diff(in_ptr)
    n_in = in_deg + hn_prev.astype(jnp.int32)                             # the in-edges whose counts may change
    lane = jnp.arange(CH, dtype=jnp.int32)
    i32 = jnp.int32

    def lanes_to_byte(counts):
        G = jnp.zeros(counts.shape, u8)
        for f in range(F):
            G |= (((counts >> (8 * f)) & 255) > 0).astype(u8) << f
        return G

    def chunks(n, body, init):
        """body(i, carry) over the chunks 0 .. ceil(n / CH) - 1 (a while loop: no work past n)."""
        return jax.lax.while_loop(lambda c: c[0] * CH < n, lambda c: (c[0] + 1, body(c[0], c[1])), (i32(0), init))[1]

    def sparse_frame(c):
        """G[t] from G[t + 1] and the states whose byte changed from G[t + 2], when frame t + 1's table is
        frame t + 2's. In place; skips the rest (over = True) when more than KX in-edge entries follow."""
        t, G, A, counts, lst, n, stamp, ya, da, ends, srcs, lval, table, kinds, nchg = c
        u = t + 1
        # nothing to do where no byte changed and the rule repeats (entry states included): a fixed point
        busy = (n > 0) | ~same_op[u] if paper else n > 0

        def work(w):
            G, A, counts, lst, n, stamp, ya, da, ends, srcs, lval = w[:11]
            tab = tables[u]

            def moved_arrivals(y, live, a, st):   # append the states whose arrival byte changes (and has in-edges)
                A, ya, da, na, nx, anye = st
                old = A[y]
                moved = live & (a != old)
                A = A.at[jnp.where(moved, y, S)].set(a, mode="drop")
                cnt = jnp.where(moved, n_in[y], 0)
                keep = cnt > 0
                pos = jnp.where(keep, na + jnp.cumsum(keep) - 1, KB)
                ya = ya.at[pos].set(y, mode="drop")
                da = da.at[pos].set(lanes_of[a] - lanes_of[old], mode="drop")
                return A, ya, da, na + jnp.sum(keep, dtype=i32), nx + jnp.sum(cnt), anye

            def arrive(i, st):        # chunk i of the changed states: their arrival byte by the frame's table
                y = jax.lax.dynamic_slice(lst, (i * CH,), (CH,))
                live = (i * CH + lane < n) & (y < last)
                if paper:
                    ent = live & is_entry[y]
                    st = st[:5] + (st[5] | jnp.any(ent),)
                    live &= ~ent                                              # the entry states: their full rule below
                y = jnp.where(live, y, last)
                return moved_arrivals(y, live, tab[lut_index[y] | G[y].astype(i32)], st)

            st = chunks(n, arrive, (A, ya, da, i32(0), i32(0), jnp.bool_(False)))
            if paper:   # the entry states' full rule: unchanged where the rule repeats and their bytes did not change
                redo = ~same_op[u] | st[5]
                st = chunks(jnp.where(redo, 1, 0), lambda i, st: moved_arrivals(entry, entry != last, entry_rule(G, u), st),
                            st)
            A, ya, da, na, nx, _ = st
            over = nx > KX
            na = jnp.where(over, 0, na)
            nx = jnp.where(over, 0, nx)

            def ending(i, st):        # running ends of each changed arrival's in-edge entries
                ends, run = st
                y = jax.lax.dynamic_slice(ya, (i * CH,), (CH,))
                cnt = jnp.where(i * CH + lane < na, n_in[y], 0)
                e = run + jnp.cumsum(cnt)
                return jax.lax.dynamic_update_slice(ends, e, (i * CH,)), e[-1]

            ends = chunks(na, ending, (ends, i32(0)))[0]

            def follow(i, st):        # chunk i of the in-edge entries: the counts of their sources updated
                counts, srcs, i0 = st    # i0: the first changed arrival whose entries start in this chunk or later
                base = i * CH
                slot = base + lane
                first = jax.lax.dynamic_slice(ends, (i0,), (CH,)) - n_in[jax.lax.dynamic_slice(ya, (i0,), (CH,))]
                here = (i0 + lane < na) & (first < base + CH)                 # a prefix: the starts are increasing
                mark = jnp.full(CH, -1, i32).at[jnp.where(here, first - base, CH)].max(lane, mode="drop")
                rel = jax.lax.cummax(mark)
                item = jnp.maximum(jnp.where(rel >= 0, i0 + rel, i0 - 1), 0)  # before the first start: the item before
                y = ya[item]
                rank = slot - (ends[item] - n_in[y])
                used = slot < nx
                listed = used & (rank < in_deg[y])
                x = jnp.where(listed, in_src[jnp.minimum(in_ptr[y] + rank, in_src.shape[0] - 1)], y - 1)
                x = jnp.where(used, x, last)
                counts = counts.at[jnp.where(listed, x, S)].add(da[item], mode="drop")
                return counts, jax.lax.dynamic_update_slice(srcs, x, (base,)), i0 + jnp.sum(here, dtype=i32)

            counts, srcs, _ = chunks(nx, follow, (counts, srcs, i32(0)))

            def mark(i, stamp):       # one slot of each distinct source wins
                x = jax.lax.dynamic_slice(srcs, (i * CH,), (CH,))
                slot = i * CH + lane
                return stamp.at[jnp.where(slot < nx, x, S)].set(slot, mode="drop")

            stamp = chunks(nx, mark, stamp)

            def recompute(i, st):     # each distinct source's byte anew; the changed ones listed with their byte
                lst, lval, m = st
                x = jax.lax.dynamic_slice(srcs, (i * CH,), (CH,))
                slot = i * CH + lane
                Gx = lanes_to_byte(counts[x]) | jnp.where(has_next[x], A[jnp.minimum(x + 1, last)], u8(0))
                ch = (slot < nx) & (stamp[x] == slot) & (Gx != G[x])
                pos = jnp.where(ch, m + jnp.cumsum(ch) - 1, KX)
                return lst.at[pos].set(x, mode="drop"), lval.at[pos].set(Gx, mode="drop"), m + jnp.sum(ch, dtype=i32)

            lst2, lval, n2 = chunks(nx, recompute, (lst, lval, i32(0)))

            def write(i, G):
                x = jax.lax.dynamic_slice(lst2, (i * CH,), (CH,))
                v = jax.lax.dynamic_slice(lval, (i * CH,), (CH,))
                return G.at[jnp.where(i * CH + lane < n2, x, S)].set(v, mode="drop")

            G = chunks(n2, write, G)
            return G, A, counts, lst2, n2, stamp, ya, da, ends, srcs, lval, over, jnp.bool_(False)

        w = jax.lax.while_loop(lambda w: w[-1], work, (G, A, counts, lst, n, stamp, ya, da, ends, srcs, lval,
                                                        jnp.bool_(False), busy))
        G, A, counts, lst2, n2, stamp, ya, da, ends, srcs, lval, over = w[:12]
        row = jnp.where(over, t + 1, t)         # an overflowing frame is left to the dense pass
        table = jax.lax.dynamic_update_slice(table, G[None], (jnp.maximum(row, 0), 0))
        kinds = kinds.at[row].set(jnp.where(over, kinds[row], jnp.where(busy, 1, 2)), mode="drop")
        nchg = nchg.at[row].set(jnp.where(over, nchg[row], n2), mode="drop")
        return (jnp.where(over, t, t - 1), G, A, counts, lst2, jnp.where(over, n, n2), stamp, ya, da, ends, srcs, lval,
                table, kinds, nchg), over

    def sparse_ok(c, over):
        t = c[0]
        return (t >= 0) & ~over & same_table[jnp.minimum(t + 1, Tp - 1)]

    def dense_frame(c):
        """G[t] by the dense pass with edge counts, and (if the next frame may take the changed states)
        the list of the states whose byte changed."""
        t, G_next, A, counts, lst, n, stamp, ya, da, ends, srcs, lval, table, kinds, nchg = c
        u = t + 1
        A = jax.lax.optimization_barrier(arrival(G_next, u, tables[u]))
        counts = edge_lane_counts(lanes_of[A], src, tgt, S)
        G = lanes_to_byte(counts) | jnp.where(has_next, jnp.concatenate([A[1:], jnp.zeros(1, u8)]), u8(0))
        ch = G != G_next
        n = jnp.sum(ch, dtype=i32)
        want = (t > 0) & same_table[jnp.maximum(u - 1, 0)] & (n <= KX)

        chp = jnp.pad(ch, (0, -S % CH))

        def listing(i, st):
            lst, m = st
            c_ = jax.lax.dynamic_slice(chp, (i * CH,), (CH,))
            pos = jnp.where(c_, m + jnp.cumsum(c_) - 1, KX)
            ids = i * CH + lane
            return lst.at[pos].set(ids, mode="drop"), m + jnp.sum(c_, dtype=i32)

        lst = chunks(jnp.where(want, S, 0), listing, (lst, i32(0)))[0]
        table = jax.lax.dynamic_update_slice(table, G[None], (t, 0))
        kinds, nchg = kinds.at[t].set(0), nchg.at[t].set(n)
        return (t - 1, G, A, counts, lst, n, stamp, ya, da, ends, srcs, lval, table, kinds, nchg), ~want

    def outer(c):
        c, over = dense_frame(c)
        c, _ = jax.lax.while_loop(lambda s: sparse_ok(*s), lambda s: sparse_frame(s[0]), (c, over))
        return c

    zi, zb = jnp.zeros(KX, i32), jnp.zeros(KB, i32)
    init = (num_frames - 2, jnp.full(S, all_ones), jnp.zeros(S, u8), jnp.zeros(S, jnp.uint32), zi, i32(0),
            jnp.zeros(S, i32), zb, jnp.zeros(KB, jnp.uint32), zb, zi, jnp.zeros(KX, u8), jnp.full((Tp, S), all_ones),
            jnp.where(jnp.arange(Tp) >= num_frames - 1, -1, 0).astype(i32), jnp.zeros(Tp, i32))
    out = jax.lax.while_loop(lambda c: c[0] >= 0, outer, init)
    feas, kinds, nchg = out[12], out[13], out[14]
    ok = jnp.any(valid0 & (((feas[0] >> flag0.astype(u8)) & 1) == 1))
    return (feas, ok, (kinds, nchg)) if stats else (feas, ok)


def byte_lanes(F: int) -> np.ndarray:
    """(256,) uint32: byte a -> bit f of a in byte lane f (the changed-state look-ahead's edge counts)."""
    a = np.arange(256, dtype=np.uint32)
    return sum(((a >> f) & 1) << (8 * f) for f in range(F)).astype(np.uint32)


def edge_lane_counts(lanes, src, tgt, S: int):
    """(S,) uint32: per state and flag bit, how many of its listed edges x -> y have the bit set, one
    byte lane per bit: the sum of ``lanes[y]`` (:func:`byte_lanes` of the arrival bytes) over each
    state's rows (:func:`edge_or`'s layout; fewer than 256 listed edges per state)."""
    out = jnp.zeros(S, jnp.uint32)
    for s_k, t_k in zip(src, tgt):
        r = jnp.sum(lanes[t_k], axis=1, dtype=jnp.uint32)
        out = out.at[s_k].set(r, indices_are_sorted=True)
    return out


def feasibility(prep, constraints: Constraints, padded_inputs, capacity=None, stats: bool = False):
    """((Tp, S_pad) uint8 device array of completable (state, flags) bits (module docstring), solvable
    (a device bool)) for a graph prepared by ``beam._prepare``; ``padded_inputs``: the window's
    ``beam_kernel.WindowInputs`` (reqs, pw, reset, check, paper), padded to Tp frames exactly as the beam
    kernel gets them. ``capacity``: the changed-state buffers (:class:`SparseCapacity`,
    :func:`lookahead_capacity`; None: the dense pass); ``stats``: also the per-frame statistics of
    :func:`_feasible_kernel`."""
    c = constraints
    edges = prep.lookahead_edges(None if c.paper is None else (c.paper.own_codes, c.paper.par_codes), capacity)
    static = {"F": num_flags(c), "paper": c.paper is not None}
    if stats:
        static["stats"] = True
    return kernel_cache.call(_feasible_kernel, "feasible",
                             (edges, prep.device.state_code, prep.paper_device.segment_info, *padded_inputs,
                              np.int32(c.num_frames), np.int32(prep.num_states)), static)


def solvable(bits0, start_ok, flag0) -> bool:
    """Some start state allowed at frame 0 (``start_ok``) with its flags ``flag0`` is completable."""
    return bool(np.any(start_ok & (((np.asarray(bits0) >> flag0) & 1) == 1)))
