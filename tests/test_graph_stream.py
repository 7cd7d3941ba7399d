"""The sharded, resumable, multi-device construction (graph/stream.py) against build_graph; the
array folders (graph/store.py); the search on a memory-mapped graph."""
import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from convsynth_jax.errors import GraphError
from convsynth_jax.graph import build_database, build_graph
from convsynth_jax.graph.params import GraphParams
from convsynth_jax.graph.store import load_database, load_graph_folder, read_array_folder, save_database
from convsynth_jax.graph.stream import ShardParams, build_graph_sharded
from convsynth_jax.graph.types import MotionGraph

from test_graph_build import random_clips

GP = GraphParams(tile=16)          # small tiles: several shards on a few hundred frames
SP = ShardParams(block_tiles=2, batch=4)
REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    """(database, its folder's parent, build_graph's graph): 4 clips x 200 frames."""
    db = build_database(random_clips(7, n_clips=4, frames=200))
    d = tmp_path_factory.mktemp("stream")
    save_database(db, d / "db")
    return db, d, build_graph(db, GP)


def assert_same_graph(g, h):
    assert g.num_states == h.num_states and g.num_edges == h.num_edges
    for k in MotionGraph._ARRAYS:
        np.testing.assert_array_equal(np.asarray(getattr(g, k)), np.asarray(getattr(h, k)), err_msg=k)
    for k in ("threshold", "w_v", "num_states_before_scc", "num_edges_before_scc", "num_key_states"):
        assert g.meta[k] == h.meta[k], k


def test_sharded_build_equals_build_graph(small):
    db, d, g = small
    h = build_graph_sharded(db, GP, d / "one", SP)
    assert h.meta["kernel"]["shards"] >= 3 and h.meta["kernel"]["shards_computed"] == h.meta["kernel"]["shards"]
    assert g.num_edges > g.num_states  # synthetic transitions survive the SCC: the comparison is not vacuous
    assert_same_graph(g, h)
    # the database read back from its folder (memory-mapped) gives the same graph
    db2 = load_database(d / "db")
    assert isinstance(db2.positions, np.memmap)
    assert_same_graph(g, build_graph_sharded(db2, GP, d / "mapped", SP))


def test_capped_and_filtered_build_equals_build_graph(small):
    """The out-degree cap (kept per source while streaming) and the seam filter apply in
    build_graph's order; more candidates than max_edges stop with a GraphError."""
    db, d, _ = small
    gp = GraphParams(tile=16, max_out_degree=2, seam_filter_quantile=0.9)
    h = build_graph_sharded(db, gp, d / "capped", SP)
    g = build_graph(db, gp)
    k = h.meta["kernel"]
    assert k["seam_dropped"] > 0 and k["candidates_found"] > h.meta["num_synthetic_before_scc"] + k["seam_dropped"]
    assert_same_graph(g, h)
    with pytest.raises(GraphError, match="more than graph.max_edges=5 candidate transitions in shard"):
        build_graph_sharded(db, GraphParams(tile=16, max_edges=5), d / "limited", SP)


CHILD = """
import os, signal, sys
import jax
from convsynth_jax.graph.params import GraphParams
from convsynth_jax.graph.store import load_database
from convsynth_jax.graph.stream import ShardParams, build_graph_sharded
d = sys.argv[1]
assert len(jax.devices()) == 4, jax.devices()
db = load_database(d + "/db")
gp, sp = GraphParams(tile=16), ShardParams(block_tiles=2, batch=4)
build_graph_sharded(db, gp, d + "/four", sp)
def kill(b, n):
    if b == 1:
        os.kill(os.getpid(), signal.SIGKILL)
build_graph_sharded(db, gp, d + "/killed", sp, on_shard=kill)
"""


def test_four_devices_and_resume_after_sigkill(small):
    """A child process on 4 forced CPU devices builds the whole graph (same as one device), then
    starts another build and SIGKILLs itself after its second shard; the build run again here (one
    device) resumes from those shards and gives the uninterrupted graph."""
    db, d, g = small
    env = dict(os.environ, XLA_FLAGS=f"{os.environ.get('XLA_FLAGS', '')} --xla_force_host_platform_device_count=4",
               JAX_PLATFORMS="cpu")
    r = subprocess.run([sys.executable, "-c", textwrap.dedent(CHILD), str(d)], env=env, cwd=REPO,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == -9, r.stderr[-3000:]
    four = load_graph_folder(d / "four" / "graph")
    assert four.meta["kernel"]["devices"] == 4
    assert_same_graph(g, four)
    man = json.loads((d / "killed" / "manifest.json").read_text())
    assert "graph" not in man
    assert sorted(f.name for f in (d / "killed" / "shards").glob("*.json")) == ["edges_00000.json", "edges_00001.json"]
    assert not (d / "killed" / "graph").exists()
    h = build_graph_sharded(db, GP, d / "killed", SP)
    assert h.meta["kernel"]["shards_resumed"] == 2
    assert h.meta["kernel"]["shards_computed"] == h.meta["kernel"]["shards"] - 2
    assert_same_graph(g, h)


def test_two_processes_share_one_folder(small):
    """Processes split the blocks (every second one); the first assembles once all are there."""
    db, d, g = small
    out = d / "two"
    assert build_graph_sharded(db, GP, out, ShardParams(2, 4, process_index=0, process_count=2)) is None  # waits
    assert build_graph_sharded(db, GP, out, ShardParams(2, 4, process_index=1, process_count=2)) is None
    h = build_graph_sharded(db, GP, out, ShardParams(2, 4, process_index=0, process_count=2))
    assert h.meta["kernel"]["shards_computed"] == 0 and h.meta["kernel"]["processes"] == 2
    assert_same_graph(g, h)


def test_corrupt_shard_is_rebuilt_and_other_params_refused(small):
    db, d, g = small
    out = d / "corrupt"
    build_graph_sharded(db, GP, out, SP)
    shard = out / "shards" / "edges_00001.npz"
    shard.write_bytes(shard.read_bytes()[:-7])  # truncated
    h = build_graph_sharded(db, GP, out, SP)
    assert h.meta["kernel"]["shards_computed"] == 1
    assert_same_graph(g, h)
    with pytest.raises(GraphError, match="another database or other parameters"):
        build_graph_sharded(db, GraphParams(tile=16, quantile=0.9), out, SP)
    f = out / "graph" / "cost.npy"
    f.write_bytes(f.read_bytes()[:-4] + b"\0\0\0\1")
    with pytest.raises(GraphError, match="checksum mismatch.*cost"):
        read_array_folder(out / "graph")


def test_beam_search_on_memory_mapped_graph(small):
    """The beam search (with its look-ahead) reads the graph folder memory-mapped and finds the same
    path as on the in-memory graph."""
    from convsynth_jax.search.beam import beam_search
    from convsynth_jax.search.constraints import build_constraints
    from convsynth_jax.search.params import SearchParams

    db, d, g = small
    build_graph_sharded(db, GP, d / "search", SP)
    mm = load_graph_folder(d / "search" / "graph", mmap=True)
    assert isinstance(mm.indices, np.memmap)
    sp = SearchParams()
    none = pd.DataFrame({"kind": [], "start": [], "end": [], "peak": []})
    c = build_constraints(none, none, 60, 30.0, sp)  # an idle window: every state's label matches
    a, b = beam_search(g, c, sp, seed=0), beam_search(mm, c, sp, seed=0)
    assert a.success and b.success
    np.testing.assert_array_equal(a.path, b.path)
