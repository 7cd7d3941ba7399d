"""Task ``build_graph_sharded``: the sharded, resumable, multi-device graph construction
(graph/stream.py) of a database folder written by ``task=make_scale_db``.

    convsynth task=build_graph_sharded task.db=DIR [task.out=DIR] [task.block_tiles=64] [graph.KEY=...]

Run it again with the same ``task.out`` after a crash or kill: finished shards are kept. The graph is
written to ``<out>/graph`` (memory-mappable array folder); ``summary.json`` gives its size and timings.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

KEYS = ("num_frames", "num_key_states", "threshold", "w_v", "num_states_before_scc", "num_edges_before_scc",
        "num_states", "num_edges", "num_synthetic_edges", "seconds", "timings", "kernel", "scc_warning")


@dataclass(frozen=True)
class BuildGraphShardedSettings:
    """``conf/task/build_graph_sharded.yaml``."""

    name: str = "build_graph_sharded"
    db: Optional[str] = None        # database folder (task=make_scale_db)
    out: Optional[str] = None       # build folder (None: <run dir>/graph_build)
    block_tiles: int = 64           # source tiles per shard
    batch: int = 16                 # tile pairs per device per kernel call
    devices: Optional[int] = None   # the first this many of the process's JAX devices (None: all)
    distributed: bool = False       # jax.distributed.initialize() first (one process per host, e.g. Slurm)


def run(cfg, out_dir: Path) -> dict:
    from ..config import task_settings
    from ..errors import ConfigError
    from ..graph.store import load_database
    from ..graph.stream import ShardParams, build_graph_sharded
    from .common import params_of

    s = task_settings(cfg)
    if not s.db:
        raise ConfigError("build_graph_sharded needs task.db=DIR (a folder written by task=make_scale_db)",
                          where="task.db")
    params = params_of(cfg)
    if s.distributed:
        import jax

        jax.distributed.initialize()  # on Slurm: coordinator, process count and index from SLURM_* variables
    db = load_database(s.db)
    out = Path(s.out) if s.out else out_dir / "graph_build"
    t0, c0 = time.perf_counter(), time.process_time()
    g = build_graph_sharded(db, params.graph, out, ShardParams(s.block_tiles, s.batch, s.devices))
    if g is None:  # another process assembles (or shards of others are missing)
        return {"build": str(out), "assembled": False, "wall_seconds": time.perf_counter() - t0}
    res = {k: g.meta.get(k) for k in KEYS}
    res.update(build=str(out), wall_seconds=time.perf_counter() - t0, cpu_seconds=time.process_time() - c0)
    return res
