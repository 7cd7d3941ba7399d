"""A graph made ready for the beam search and the look-ahead (:mod:`.beam`, :mod:`.feasible`): each
state's kept out-edges as flat arrays, the packed state codes, and the kernels' arguments as named
tuples (device and host copies). Padding and the per-graph cache live in :mod:`.beam`."""
from __future__ import annotations

import dataclasses
from typing import NamedTuple

import jax
import numpy as np

from ..errors import LabelError
from .constraints import is_peak_state
from .feasible import lookahead_edges, pad_lookahead


class GraphArrays(NamedTuple):
    """The beam kernel's graph (device arrays): state s's kept edges, cheapest first, are entries
    first_edge[s] .. first_edge[s] + degree[s] - 1 of packed / cost. States padded (S_pad,), edges (E_pad,)."""
    first_edge: object   # (S_pad,) int32
    packed: object       # (E_pad,) int32: target << CODE_BITS | the target's state code
    cost: object         # (E_pad,) float32 (inf on padding edges)
    degree: object       # (S_pad,) int32 (0 on padding states)
    state_code: object   # (S_pad,) int32 (:func:`state_codes`)


class PaperGraphArrays(NamedTuple):
    """What ``search.matching=paper`` adds (device arrays)."""
    synthetic: object     # (E_pad,) bool: the flat edge is a synthetic transition
    segment_info: object  # (S_pad, 5) int32: constraints.segment_info


class HostGraph(NamedTuple):
    """Host copies for the look-ahead's edge lists (``feasible.lookahead_edges``), states padded."""
    first: np.ndarray         # (S_pad,)
    degree: np.ndarray        # (S_pad,)
    targets: np.ndarray       # (E,)
    synthetic: np.ndarray     # (E,)
    segment_info: np.ndarray  # (S_pad, 5)
    state_code: np.ndarray    # (S_pad,)


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
class PreparedGraph:
    """A graph made ready for the kernels (cached per graph object; graphs are immutable). Edges are
    flat (:func:`kept_edges`): state s's kept edges are entries first[s] .. first[s] + deg[s] - 1."""
    first: np.ndarray        # (S,) host copies, for the path's statistics
    cost: np.ndarray         # (E,)
    syn: np.ndarray          # (E,)
    max_degree: int          # D: the largest kept degree
    median_syn: float        # median synthetic edge cost: the temperature's unit
    device: GraphArrays      # device arrays; states padded to STATE_BUCKET, edges to EDGE_BUCKET (+ D, so
    #                          first + rank never runs over)
    paper_device: PaperGraphArrays   # for search.matching=paper
    host: HostGraph          # host arrays of the look-ahead's lists, states padded
    num_states: int
    kernel_degree: int = 0   # the kernels' static D: max_degree, or the largest of a group sharing shapes
    peers: tuple = ()        # the group's graphs' PreparedGraph (share_shapes): look-ahead lists padded alike
    _edges: dict = dataclasses.field(default_factory=dict)
    _own_edges: dict = dataclasses.field(default_factory=dict)

    def edge_stats(self, src: np.ndarray, rank: np.ndarray):
        """(costs, synthetic flags) of the edges taken from states ``src`` at edge ranks ``rank``."""
        e = self.first[src] + rank
        return self.cost[e], self.syn[e]

    def lookahead_edges(self, codes=None, capacity=None):
        """The look-ahead's edge lists (feasible.LookaheadEdges, device arrays) for a ``paper`` window
        with (own codes, partner codes), or for ``labels`` (None); built once per codes. ``capacity``:
        the changed-state look-ahead's buffers (``feasible.SparseCapacity``, ``search.lookahead_pass``
        through ``feasible.lookahead_capacity``; "auto": by the graph's size; None: the dense pass)."""
        key = (None if codes is None else (int(codes[0]), int(codes[1])), capacity)
        if key not in self._edges:
            e = self.own_lookahead_edges(key)
            if self.peers:   # a group sharing one compiled kernel: every member's lists, padded alike
                own = [p.own_lookahead_edges(key) for p in self.peers]
                rows = [max(x.src[k].shape[0] for x in own) for k in range(len(e.src))]
                flat = None if e.sparse is None else max(x.sparse.in_src.shape[0] for x in own)
                e = pad_lookahead(e, rows, max(x.entry.shape[0] for x in own), flat)
            self._edges[key] = jax.tree.map(jax.device_put, e)
        return self._edges[key]

    def own_lookahead_edges(self, key):
        """This graph's look-ahead lists for ``key`` = (codes, capacity) on its own (host arrays, built
        once per key)."""
        if key not in self._own_edges:
            self._own_edges[key] = lookahead_edges(*self.host, self.num_states, key[0], max_degree=self.kernel_degree,
                                                   capacity=key[1])
        return self._own_edges[key]
