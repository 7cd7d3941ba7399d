"""Sharded, resumable, multi-device motion-graph construction (paper Section 6 at scale; ours).

The same graph as :func:`convsynth_jax.graph.build.build_graph` (tests/test_graph_stream.py), built
so that a database of millions of frames fits in bounded memory and a killed build resumes:

1. the construction plan (w_v, key states, the fit of c(i, i+k) and the threshold;
   :func:`~convsynth_jax.graph.build.construction_plan`) is computed as usual; it is deterministic;
2. the source key states are tiled (k-d order of their pivot distances, as in graph/cost.py) and the
   source tiles cut into *blocks* of ``block_tiles`` tiles. A block's candidate transitions
   (Eq. 3-4: c(i, j) = D(i, j - 1) < threshold, against every destination tile not ruled out by
   the triangle inequality) are computed tile pair batch by batch, filtered (per-edge filters and the
   out-degree cap, all of which only look at one source's edges) and written as one shard
   ``shards/edges_<block>.npz``, then its sidecar ``edges_<block>.json`` (sha256, edge count).
   ``manifest.json`` holds the plan's fingerprint. Every write is atomic (temporary name, then
   rename), so a build killed at any point (SIGKILL included) leaves only whole shards, and the next
   run with the same database and parameters skips every shard whose sidecar checksum matches;
3. the shards are read back (int32 frame indices) and the original transitions added; the largest
   strongly connected component (scipy.sparse.csgraph) gives the graph, written as a memory-mappable
   array folder (graph/store.py) that the search reads as it is.

Memory: the edge stage holds the features, the tilings and one block's candidates (with
``graph.max_out_degree``: a per-source table of the cap cheapest; without: every candidate, at most
``graph.max_edges`` or a GraphError naming the shard), so it does not grow with the edge count; the
assembly holds the kept synthetic transitions (the SCC needs them): about 35 bytes each at its peak.

Devices: a batch of tile pairs is one call of a vmapped tile kernel under ``shard_map`` over a 1-D
mesh of all (or the given) JAX devices, the pairs split evenly across them; every pair's costs are
the same arithmetic on any device count, so the edges are the same (tests run it on 4 forced CPU
devices). Across hosts: one process per host (``jax.distributed.initialize()``, docs/scale.md), each
on its own devices and every ``process_count``-th block, writing into one shared folder; after a
barrier the first process assembles the graph.

``local_minima`` (a neighbourhood rule across sources) is not supported here.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import logging
import time
from dataclasses import dataclass
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, PartitionSpec
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from ..errors import ConfigError, GraphError
from ..utils import write_json_atomic
from .build import assemble_graph, construction_meta, construction_plan, scc_warning
from .cost import BOUND_MARGIN, CheapestPerSource, _keep_cheapest, _sum_of_norms, _tile_lower_bounds, _tiling, pivot_embedding
from .database import MotionDatabase
from .params import GraphParams
from .seams import apply_glitch_filter, frame_acceleration, seam_filter_mask
from .store import file_sha256, load_graph_folder, save_graph_folder, save_npz_atomic
from .types import MotionGraph

try:  # jax >= 0.4.35
    from jax import shard_map as _shard_map
except ImportError:  # pragma: no cover - older jax
    from jax.experimental.shard_map import shard_map as _shard_map

log = logging.getLogger(__name__)

FORMAT = "convsynth-sharded-graph-1"


@dataclass(frozen=True)
class ShardParams:
    """How the sharded build cuts and dispatches the work (not what it computes: any values give
    the same graph)."""

    block_tiles: int = 64     # source tiles per shard (a shard's sources: block_tiles * graph.tile)
    batch: int = 16           # tile pairs per device per kernel call
    devices: int | None = None  # use the first this many of the process's JAX devices (None: all)
    # several processes (hosts) on one build folder: process i computes blocks i, i + n, ...; the
    # first assembles. None: jax.process_index() / jax.process_count() (1 process without
    # jax.distributed)
    process_index: int | None = None
    process_count: int | None = None

    def __post_init__(self):
        if int(self.block_tiles) < 1 or int(self.batch) < 1:
            raise ConfigError(f"block_tiles and batch must be >= 1, got {self.block_tiles}, {self.batch}",
                              where="shards")


def _tile_costs_one(xa, xb, ia, ib, ca, cb, threshold, min_gap):
    """:func:`~convsynth_jax.graph.cost.masked_tile_costs` of one gathered tile pair.
    xa: (M, 3, T), xb: (M, 3, T); ia, ib, ca, cb: (T,) int32 -> (T, T) float32."""
    d = _sum_of_norms(xa, xb)
    near = (ca[:, None] == cb[None, :]) & (jnp.abs(ia[:, None] - ib[None, :]) <= min_gap)
    ok = (d < threshold) & ~near & (ia[:, None] >= 0) & (ib[None, :] >= 0)
    return jnp.where(ok, d, jnp.inf)


_KERNELS: dict = {}


def tile_kernel(devices):
    """The jitted batch kernel over a 1-D mesh of ``devices``: (P, M, 3, T) x2, (P, T) int32 x4,
    threshold, min_gap -> (P, T, T) float32, P a multiple of len(devices), split across them."""
    key = tuple(d.id for d in devices)
    if key not in _KERNELS:
        mesh = Mesh(np.asarray(devices), ("tiles",))
        spec, rep = PartitionSpec("tiles"), PartitionSpec()
        body = jax.vmap(_tile_costs_one, in_axes=(0, 0, 0, 0, 0, 0, None, None))
        _KERNELS[key] = jax.jit(_shard_map(body, mesh=mesh, in_specs=(spec,) * 6 + (rep, rep), out_specs=spec))
    return _KERNELS[key]


def _fingerprint(*parts) -> str:
    h = hashlib.sha256()
    for p in parts:
        if isinstance(p, np.ndarray):
            h.update(str((p.dtype, p.shape)).encode())
            h.update(np.ascontiguousarray(p).tobytes())
        else:
            h.update(json.dumps(p, sort_keys=True, default=str).encode())
    return h.hexdigest()


class _EdgeStage:
    """The tilings, live tile pairs and blocks of one build (deterministic from db, params, plan)."""

    def __init__(self, db: MotionDatabase, params: GraphParams, plan, block_tiles: int):
        keys, X = plan.keys, plan.features
        src = np.flatnonzero(keys).astype(np.int64)
        dst = src[db.frame[src] > 0] - 1  # j - 1 must be in the same clip
        self.src, self.dst = src, dst
        self.threshold = float(plan.threshold)
        clip = np.asarray(db.clip, np.int64)
        tile = int(params.tile)
        if src.size == 0 or dst.size == 0 or not self.threshold > 0:
            self.pairs = np.zeros((0, 2), np.int64)
            self.blocks = []
            self.ta = self.tb = None
            self.pivots = 0
            return
        rng = np.random.default_rng(int(params.seed))
        union = np.union1d(src, dst)
        if int(params.n_pivots) > 0:
            piv, emb_all = pivot_embedding(X, union, int(params.n_pivots), rng)
        else:
            piv, emb_all = np.zeros(0, np.int64), np.zeros((union.size, 0))
        self.pivots = int(piv.size)
        emb_of = lambda idx: emb_all[np.searchsorted(union, idx)]  # noqa: E731
        ta = _tiling(X, src, emb_of(src), clip, tile)
        tb = _tiling(X, dst, emb_of(dst), clip, tile)
        lb = _tile_lower_bounds(ta, tb)
        scale = float(np.nanmax(np.abs(emb_all))) if emb_all.size else 0.0
        self.pairs = np.argwhere(lb < self.threshold + BOUND_MARGIN * (self.threshold + scale))
        self.total_tile_pairs = int(lb.size)
        del lb
        nta = ta.ids.shape[0]
        # host copies of the real tiles (the device stacks of _tiling are padded to a power of two)
        self.ta = (ta.ids, np.asarray(ta.x)[:nta], np.asarray(ta.i32)[:nta], np.asarray(ta.c32)[:nta])
        ntb = tb.ids.shape[0]
        self.tb = (tb.ids, np.asarray(tb.x)[:ntb], np.asarray(tb.i32)[:ntb], np.asarray(tb.c32)[:ntb])
        bt = int(block_tiles)
        self.blocks = [(s, min(s + bt, nta)) for s in range(0, nta, bt)]
        self.row_start = np.searchsorted(self.pairs[:, 0], [b[0] for b in self.blocks] + [nta])

    def fingerprint(self) -> str:
        if self.ta is None:
            return _fingerprint(self.src, self.dst, self.threshold)
        return _fingerprint(self.src, self.dst, self.threshold, self.ta[0], self.tb[0], self.pairs)

    def block_pairs(self, b: int) -> np.ndarray:
        return self.pairs[self.row_start[b]:self.row_start[b + 1]]


def _block_candidates(stage: _EdgeStage, block: int, kernel, ndev: int, batch: int, min_gap: int,
                      cap: int | None = None, limit: int | None = None, where: str = ""):
    """(a, b, cost) of the candidate transitions of block ``block`` (one device call per batch of
    ``batch * ndev`` tile pairs, the next batch dispatched before the previous is compacted), and
    the number found. ``cap``: only each source's ``cap`` cheapest (ties: lower target), kept in a
    per-source table updated tile pair by tile pair, so memory stays sources x cap however many pass.
    ``limit``: more candidates than this (without a cap) raise a GraphError naming ``where``."""
    pairs = stage.block_pairs(block)
    r0, r1 = stage.blocks[block]
    ids_a, xa, ia, ca = stage.ta
    ids_b, xb, ib, cb = stage.tb
    T = ids_a.shape[1]
    step = batch * ndev
    thr, gap = np.float32(stage.threshold), np.int32(min_gap)
    out_a, out_b, out_c = [], [], []
    found = [0]
    if cap:
        best = CheapestPerSource((r1 - r0) * T, cap)

    def launch(s):
        ps = pairs[s:s + step]
        n = ps.shape[0]
        if n < step:  # pad with the first pair; the padding's results are not read
            ps = np.concatenate([ps, np.repeat(ps[:1], step - n, 0)])
        pa, pb = ps[:, 0], ps[:, 1]
        return ps[:n], kernel(xa[pa], xb[pb], ia[pa], ib[pb], ca[pa], cb[pb], thr, gap)

    def compact(ps, m):
        m = np.asarray(m)[:ps.shape[0]]
        if cap:
            fin = m < np.inf
            found[0] += int(np.count_nonzero(fin))
            live = np.flatnonzero(fin.any(axis=(1, 2)))
            if live.size == 0:
                return
            for q in live:
                best.add(slice((ps[q, 0] - r0) * T, (ps[q, 0] - r0 + 1) * T), m[q], ids_b[ps[q, 1]])
            return
        t, r, c = np.nonzero(m < np.inf)
        if t.size:
            out_a.append(ids_a[ps[t, 0], r])
            out_b.append(ids_b[ps[t, 1], c])
            out_c.append(m[t, r, c])
            found[0] += int(t.size)
        if limit is not None and found[0] > limit:
            raise GraphError(f"more than graph.max_edges={limit} candidate transitions in {where} (at least "
                             f"{found[0]}); set graph.max_out_degree, or lower graph.quantile or graph.key_fraction")

    pending = None
    for s in range(0, pairs.shape[0], step):
        nxt = launch(s)
        if pending is not None:
            compact(*pending)
        pending = nxt
    if pending is not None:
        compact(*pending)
    if cap:
        a, b, c = best.edges(ids_a[r0:r1].reshape(-1))
        out_a, out_b, out_c = [a], [b], [c]
    if not out_a or out_a[0].size == 0 and len(out_a) == 1:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.float32), found[0]
    a, b, c = (np.concatenate(out_a).astype(np.int64), np.concatenate(out_b).astype(np.int64),
               np.concatenate(out_c).astype(np.float32))
    if cap:
        a, b, c = _keep_cheapest(a, b, c, cap)
    return a, b, c, found[0]


def _filters(db, params, acc):
    """The per-edge filters of build_graph (seam, glitch), applied to one block's edges after the
    out-degree cap, in build_graph's order (each looks at one edge, so blockwise equals whole)."""
    def apply(a, j, c, counts):
        if params.seam_filter_quantile is not None:
            keep, limit = seam_filter_mask(db, a, j, params.seam_filter_quantile, int(params.seam_filter_radius), acc=acc)
            counts["seam_dropped"] = counts.get("seam_dropped", 0) + int((~keep).sum())
            a, j, c = a[keep], j[keep], c[keep]
        m: dict = {}
        a, j, c = apply_glitch_filter(db, a, j, c, params, meta=m)
        if "glitch_filter" in m:
            counts["glitch_dropped"] = counts.get("glitch_dropped", 0) + m["glitch_filter"]["dropped"]
        return a, j, c
    return apply


def _shard_entry(out: Path, b: int) -> dict | None:
    """The sidecar of shard ``b`` if it and its shard file are whole (checksum), else None."""
    side = out / "shards" / f"edges_{b:05d}.json"
    if not side.is_file():
        return None
    try:
        e = json.loads(side.read_text())
    except ValueError:
        return None
    f = out / e.get("file", "")
    return e if f.is_file() and file_sha256(f) == e.get("sha256") else None


def build_graph_sharded(db: MotionDatabase, params: GraphParams, out_dir: str | Path,
                        shards: ShardParams | None = None, on_shard=None, timings: dict | None = None):
    """Build the motion graph of ``db`` into ``out_dir`` (``manifest.json``, ``shards/``, ``graph/``),
    resuming from the finished shards of an earlier run with the same database and parameters.
    Returns the graph (its arrays memory-mapped from ``out_dir/graph``); or None in a process other
    than the first of several (``ShardParams.process_count``), or in the first when shards of the
    others are still missing (run it again once they have finished). ``on_shard(block, n_blocks)``
    is called after each shard is committed (progress; tests use it to kill the build)."""
    sp = shards or ShardParams()
    p = params
    if p.local_minima:
        raise ConfigError("graph.local_minima is not supported by the sharded build (its rule spans sources)",
                          where="graph.local_minima")
    index, count = sp.process_index, sp.process_count
    if index is None:
        index, count = jax.process_index(), jax.process_count()
    if not 0 <= int(index) < int(count):
        raise ConfigError(f"process_index must lie in [0, process_count), got {index} of {count}", where="shards")
    out = Path(out_dir)
    (out / "shards").mkdir(parents=True, exist_ok=True)
    tm = timings if timings is not None else {}
    t0 = time.perf_counter()
    plan = construction_plan(db, p, tm)
    t1 = time.perf_counter()
    stage = _EdgeStage(db, p, plan, sp.block_tiles)
    tm["tiling_s"] = time.perf_counter() - t1
    graph_keys = {k: v for k, v in dataclasses.asdict(p).items() if k not in ("workers", "max_edges")}
    fp = _fingerprint(np.asarray(db.positions[:: max(1, db.num_frames // 4096)]), np.asarray(db.clip[::997]),
                      db.num_frames, graph_keys, int(sp.block_tiles), stage.fingerprint())
    man_path = out / "manifest.json"
    nb = len(stage.blocks)
    manifest = {"format": FORMAT, "fingerprint": fp, "num_frames": int(db.num_frames), "num_blocks": nb}
    if man_path.is_file():
        try:
            old = json.loads(man_path.read_text())
        except ValueError as e:
            raise GraphError(f"unreadable build manifest ({e}); delete the folder to start over", man_path) from None
        if old.get("fingerprint") != fp:
            raise GraphError("this folder holds a build of another database or other parameters; use a new "
                             "folder or delete it to start over", man_path)
    else:
        write_json_atomic(man_path, manifest)  # the same content from every process
    for stale in (out / "shards").glob(".edges_*"):  # temporaries of a killed write
        stale.unlink(missing_ok=True)
    # this process's devices (with jax.distributed, jax.devices() also lists the other hosts')
    local = jax.local_devices()
    devices = local[: sp.devices] if sp.devices else local
    kernel = tile_kernel(devices)
    acc = frame_acceleration(db) if p.seam_filter_quantile is not None else None
    filt = _filters(db, p, acc)
    t1 = time.perf_counter()
    resumed = computed = 0
    idx = np.int32 if db.num_frames < 2**31 - 1 else np.int64
    for b in range(int(index), nb, int(count)):
        if _shard_entry(out, b) is not None:
            resumed += 1
            continue
        name = f"edges_{b:05d}.npz"
        a, bb, c, found = _block_candidates(stage, b, kernel, len(devices), int(sp.batch),
                                            int(p.min_gap_frames), cap=p.max_out_degree, limit=p.max_edges,
                                            where=f"shard {b} of {out}")
        counts: dict = {}
        a, j, c = filt(a, bb + 1, c, counts)
        sha = save_npz_atomic(out / "shards" / name, a=a.astype(idx), j=j.astype(idx), c=c.astype(np.float32))
        write_json_atomic(out / "shards" / f"edges_{b:05d}.json",
                          {"file": f"shards/{name}", "sha256": sha, "edges": int(a.size), "candidates_found": found,
                           "tile_pairs": int(stage.block_pairs(b).shape[0]), **counts})
        computed += 1
        log.info("shard %d/%d: %d tile pairs, %d edges", b + 1, nb, stage.block_pairs(b).shape[0], a.size)
        if on_shard is not None:
            on_shard(b, nb)
    tm["edges_s"] = time.perf_counter() - t1
    if jax.process_count() > 1:
        from jax.experimental import multihost_utils

        multihost_utils.sync_global_devices("convsynth_jax sharded graph: shards written")
    if int(index) != 0:
        return None
    entries = [_shard_entry(out, b) for b in range(nb)]
    missing = [b for b, e in enumerate(entries) if e is None]
    if missing:
        log.info("%d of %d shards not finished yet (first: %d); run again to assemble the graph", len(missing), nb,
                 missing[0])
        return None
    total = sum(int(e["edges"]) for e in entries)
    if p.max_edges is not None and total > int(p.max_edges):
        raise GraphError(f"the shards hold {total} synthetic transitions, more than graph.max_edges={p.max_edges}; "
                         "set graph.max_out_degree, or lower graph.quantile or graph.key_fraction", out)
    t1 = time.perf_counter()
    kstats = {"tiles_computed": int(stage.pairs.shape[0]),
              "tiles_skipped": int(getattr(stage, "total_tile_pairs", 0) - stage.pairs.shape[0]),
              "tile": int(p.tile), "pivots": stage.pivots, "symmetric": False,
              "pairs_evaluated": int(stage.pairs.shape[0]) * int(p.tile) ** 2,
              "candidates_found": int(sum(e["candidates_found"] for e in entries)),
              "shards": nb, "shards_resumed": resumed, "shards_computed": computed,
              "devices": len(devices), "processes": int(count)}
    for k in ("seam_dropped", "glitch_dropped"):
        if any(k in e for e in entries):
            kstats[k] = int(sum(e.get(k, 0) for e in entries))
    meta = construction_meta(db, p, plan, kstats)
    g = assemble_graph_compact(db, plan.keys, *read_shards(out, entries, db.num_frames), meta)  # no other reference
    tm["scc_s"] = time.perf_counter() - t1
    g.meta["seconds"] = time.perf_counter() - t0
    g.meta["timings"] = dict(tm)
    save_graph_folder(g, out / "graph")
    write_json_atomic(man_path, {**manifest, "graph": {"folder": "graph", "num_states": g.num_states,
                                                       "num_edges": g.num_edges}})
    return load_graph_folder(out / "graph", mmap=True, verify=False)


def assemble_graph_compact(db: MotionDatabase, keys, a, j, c, meta: dict) -> MotionGraph:
    """:func:`~convsynth_jax.graph.build.assemble_graph` (the same graph, tests compare) in about a
    third of its memory: 32-bit edge arrays and edge numbers, the inputs consumed as it goes.
    ``a``, ``j``, ``c``: the synthetic transitions (E,), released by the caller."""
    n = db.num_frames
    if n >= 2**31 - 1 or a.size + n >= 2**31 - 1:
        return assemble_graph(db, keys, a, j, c, meta)
    clip = np.asarray(db.clip)
    t = np.flatnonzero(clip[:-1] == clip[1:]).astype(np.int32)
    rows = np.concatenate([t, a.astype(np.int32)])
    cols = np.concatenate([t + 1, j.astype(np.int32)])
    del a, j
    E = rows.size
    meta = dict(meta, num_states_before_scc=int(n), num_edges_before_scc=int(E), num_synthetic_before_scc=int(E - t.size))
    # CSR by the linear-time COO -> CSR conversion carrying each edge's number (+1) as its value
    adj = csr_matrix((np.arange(1, E + 1, dtype=np.int32), (rows, cols)), shape=(n, n))
    del rows, cols
    adj.sort_indices()
    if adj.nnz != E:
        raise GraphError(f"duplicate transitions in the edge list ({E - adj.nnz})")
    order = adj.data - 1
    n_orig = t.size
    cost = np.where(order < n_orig, np.float32(0), c[np.maximum(order - n_orig, 0)]).astype(np.float32)
    syn = order >= n_orig
    del order
    ncomp, labels = connected_components(adj, directed=True, connection="strong")
    keep = labels == int(np.argmax(np.bincount(labels)))
    del labels
    new_id = np.full(n, -1, np.int64)
    new_id[keep] = np.arange(int(keep.sum()))
    src = np.repeat(np.arange(n, dtype=np.int32), np.diff(adj.indptr))
    e = keep[src] & keep[adj.indices]
    r = src[e]
    del src
    cc, co, sy = new_id[adj.indices[e]], cost[e], syn[e]
    del adj, cost, syn, e
    S = int(keep.sum())
    indptr = np.concatenate([[0], np.cumsum(np.bincount(new_id[r], minlength=S))]).astype(np.int64)
    del r
    meta.update(num_states=S, num_edges=int(cc.size), num_synthetic_edges=int(sy.sum()), num_components=int(ncomp),
                scc_warning=scc_warning(S, n, int(cc.size), meta.get("k")))
    if meta["scc_warning"]:
        log.warning("%s", meta["scc_warning"])
    return MotionGraph(
        clip_names=db.clip_names, fps=db.fps, clip=np.asarray(db.clip)[keep], frame=np.asarray(db.frame)[keep],
        own_label=np.asarray(db.own.label)[keep], own_start=np.asarray(db.own.seg_start)[keep],
        own_end=np.asarray(db.own.seg_end)[keep], own_peak=np.asarray(db.own.seg_peak)[keep],
        partner_label=np.asarray(db.partner.label)[keep], partner_start=np.asarray(db.partner.seg_start)[keep],
        partner_end=np.asarray(db.partner.seg_end)[keep], is_key=keys[keep],
        indptr=indptr, indices=cc.astype(np.int64), cost=co, synthetic=sy, meta=meta)


def read_shards(out_dir: str | Path, entries: list, num_frames: int):
    """(a, j, c) of the shards described by ``entries`` (their sidecars, in block order)."""
    out = Path(out_dir)
    total = sum(int(e["edges"]) for e in entries)
    idx = np.int32 if total < 2**31 - 1 and num_frames < 2**31 - 1 else np.int64
    a = np.empty(total, idx)
    j = np.empty(total, idx)
    c = np.empty(total, np.float32)
    pos = 0
    for e in entries:
        with np.load(out / e["file"]) as z:
            k = z["a"].size
            a[pos:pos + k], j[pos:pos + k], c[pos:pos + k] = z["a"], z["j"], z["c"]
        pos += k
    return a, j, c
