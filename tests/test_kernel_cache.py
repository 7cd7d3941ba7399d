"""Compiled kernels kept between runs (convsynth_jax/kernel_cache.py): a stored
kernel gives the same outputs as the jitted one, a stale, corrupt or truncated file is never used (it
is ignored and written anew), and deleting the folder is safe. No timing assertions."""
import dataclasses
import os
import shutil
import subprocess
import sys
from functools import partial
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from convsynth_jax import kernel_cache
from convsynth_jax.search.beam import beam_search, lookahead
from convsynth_jax.search.constraints import build_constraints
from convsynth_jax.search.params import SearchParams
from test_search_beam_kernel import FPS, hub_graph, input_from_clip

REPO = Path(__file__).resolve().parent.parent


@pytest.fixture
def kdir(tmp_path):
    """Kernels go to a fresh folder; each test starts with nothing loaded in the process."""
    old = kernel_cache.kernel_dir()
    kernel_cache.set_kernel_dir(tmp_path / "jax_kernels")
    kernel_cache._LOADED.clear()
    try:
        yield tmp_path / "jax_kernels"
    finally:
        kernel_cache.set_kernel_dir(old)
        kernel_cache._LOADED.clear()


@partial(jax.jit, static_argnames=("scale",))
def _toy(x, pair, scale: int):
    a, b = pair
    return jnp.cumsum(x * scale) + a.sum(), (b[::-1] * 2, x.shape[0])


def _files(d: Path):
    return sorted(d.glob(f"*{kernel_cache.SUFFIX}")) if d.exists() else []


def test_stored_kernel_equals_jitted_and_is_stored(kdir):
    x, pair = np.arange(5, dtype=np.float32), (np.ones(3, np.int32), np.arange(4, dtype=np.int32))
    want = _toy(x, pair, scale=3)
    got = kernel_cache.call(_toy, "toy", (x, pair), {"scale": 3})
    assert len(_files(kdir)) == 1
    for g, w in zip(jax.tree.leaves(got), jax.tree.leaves(want)):
        np.testing.assert_array_equal(np.asarray(g), np.asarray(w))
    # another static argument or shape is another file; the same call again reads the stored one
    kernel_cache.call(_toy, "toy", (x, pair), {"scale": 4})
    kernel_cache.call(_toy, "toy", (x[:4], pair), {"scale": 3})
    assert len(_files(kdir)) == 3
    kernel_cache._LOADED.clear()
    again = kernel_cache.call(_toy, "toy", (x, pair), {"scale": 3})
    np.testing.assert_array_equal(np.asarray(again[0]), np.asarray(want[0]))
    assert len(_files(kdir)) == 3
    shutil.rmtree(kdir)                    # safe to delete: compiled and stored again
    kernel_cache._LOADED.clear()
    again = kernel_cache.call(_toy, "toy", (x, pair), {"scale": 3})
    np.testing.assert_array_equal(np.asarray(again[0]), np.asarray(want[0]))
    assert len(_files(kdir)) == 1


@pytest.mark.parametrize("damage", ["truncate", "flip", "other_key", "garbage"])
def test_damaged_file_is_ignored_and_rewritten(kdir, damage):
    x, pair = np.arange(6, dtype=np.float32), (np.ones(2, np.int32), np.arange(3, dtype=np.int32))
    want = np.asarray(_toy(x, pair, scale=2)[0])
    kernel_cache.call(_toy, "toy", (x, pair), {"scale": 2})
    (path,) = _files(kdir)
    good = path.read_bytes()
    if damage == "truncate":
        bad = good[:len(good) // 2]
    elif damage == "flip":
        bad = bytearray(good); bad[-20] ^= 0xFF; bad = bytes(bad)
    elif damage == "other_key":   # a complete file written for another key (e.g. renamed): never used
        other = _files(kdir)
        kernel_cache.call(_toy, "toy", (x, pair), {"scale": 5})
        bad = [p for p in _files(kdir) if p not in other][0].read_bytes()
    else:
        bad = b"not a kernel"
    path.write_bytes(bad)
    kernel_cache._LOADED.clear()
    got = kernel_cache.call(_toy, "toy", (x, pair), {"scale": 2})
    np.testing.assert_array_equal(np.asarray(got[0]), want)
    key = path.name[len("toy-"):-len(kernel_cache.SUFFIX)]
    assert path.read_bytes() != bad and kernel_cache._read(path, key) is not None   # written anew, complete


def test_stale_source_gives_another_key(kdir, monkeypatch):
    """The key holds the source hash of the kernel's folder: after an edit the old files are not read."""
    from convsynth_jax.search import beam

    x, pair = np.arange(3, dtype=np.float32), (np.ones(1, np.int32), np.arange(2, dtype=np.int32))
    k0 = kernel_cache.kernel_key(_toy, "toy", (x, pair), {"scale": 1})
    assert kernel_cache.kernel_key(_toy, "toy", (x, pair), {"scale": 2}) != k0
    assert kernel_cache.kernel_key(_toy, "toy", (x[:2], pair), {"scale": 1}) != k0
    env = dict(kernel_cache._environment(_toy) and kernel_cache._ENV)
    monkeypatch.setattr(kernel_cache, "_ENV", {f: e + " edited" for f, e in env.items()})
    assert kernel_cache.kernel_key(_toy, "toy", (x, pair), {"scale": 1}) != k0
    monkeypatch.setattr(kernel_cache, "_ENV", {})
    k1 = kernel_cache.kernel_key(beam._beam_kernel, "beam", (x,), {})
    src = Path(beam.__file__).resolve().parent
    assert src in kernel_cache._ENV   # the search kernels hash convsynth_jax/search/
    (Path(kdir).parent / "search").mkdir()
    for p in src.glob("*.py"):
        (Path(kdir).parent / "search" / p.name).write_bytes(p.read_bytes())
    (Path(kdir).parent / "search" / "feasible.py").write_text("# edited\n", "utf-8")
    fake = type(sys)("fake_search_module"); fake.__file__ = str(Path(kdir).parent / "search" / "beam.py")
    monkeypatch.setitem(sys.modules, "fake_search_module", fake)
    edited = partial(lambda: None); edited.__module__ = "fake_search_module"
    assert kernel_cache.kernel_key(edited, "beam", (x,), {}) != k1


def test_other_xla_flags_give_another_key(monkeypatch):
    """XLA_FLAGS changes what XLA compiles (code generation, the forced device count): a kernel stored by
    a process with other flags is not loaded."""
    x = np.arange(3, dtype=np.float32)
    monkeypatch.setattr(kernel_cache, "_ENV", {})
    k0 = kernel_cache.kernel_key(_toy, "toy", (x, ()), {"scale": 1})
    monkeypatch.setenv("XLA_FLAGS", os.environ.get("XLA_FLAGS", "") + " --xla_force_host_platform_device_count=4")
    monkeypatch.setattr(kernel_cache, "_ENV", {})
    assert kernel_cache.kernel_key(_toy, "toy", (x, ()), {"scale": 1}) != k0


@pytest.mark.parametrize("matching", ["paper", "labels"])
def test_search_through_stored_kernels_equals_the_jitted_search(kdir, matching):
    """The look-ahead and the beam kernels through their stored executables, as written and as read back
    from the files: the same bits and the same path as the jitted kernels (deleting the folder is
    checked on the toy kernel, test_stored_kernel_equals_jitted_and_is_stored)."""
    g, audio = hub_graph(np.random.default_rng(3))
    own, par = input_from_clip(audio, "c3", 40)
    cfg = SearchParams(beam_size=16, max_candidates=64, max_degree=24, retry_temperatures=[], retry_beam_size=0,
                       matching=matching)
    cons = build_constraints(own, par, 40, FPS, cfg)
    kernel_cache.set_kernel_dir(None)
    want_feas, want_ok = lookahead(g, cons, 24)
    want = beam_search(g, cons, cfg, seed=3)
    kernel_cache.set_kernel_dir(kdir)
    for _ in range(2):   # compiled and written, then read back from the files
        feas, ok = lookahead(g, cons, 24)
        res = beam_search(g, cons, cfg, seed=3)
        assert {p.name.split("-")[0] for p in _files(kdir)} == {"feasible", "lookahead_beam"}
        np.testing.assert_array_equal(np.asarray(feas), np.asarray(want_feas))
        assert ok == want_ok and res.success == want.success
        if want.success:
            np.testing.assert_array_equal(res.path, want.path)
            assert res.cost == want.cost
        kernel_cache._LOADED.clear()
    kernel_cache.set_kernel_dir(None)
    want = beam_search(g, cons, dataclasses.replace(cfg, lookahead=False), seed=3)
    kernel_cache.set_kernel_dir(kdir)
    res = beam_search(g, cons, dataclasses.replace(cfg, lookahead=False), seed=3)   # the plain beam kernel
    assert "beam" in {p.name.split("-")[0] for p in _files(kdir)}
    assert res.success == want.success and (not want.success or (res.path == want.path).all())


def test_task_sets_the_kernel_folder_and_null_turns_it_off(tmp_path):
    from convsynth_jax.config import compose
    from convsynth_jax.tasks.common import enable_compilation_cache

    try:
        enable_compilation_cache(compose([f"cache_dir={tmp_path}"]))
        assert kernel_cache.kernel_dir() == (tmp_path / "jax_kernels").resolve()
        enable_compilation_cache(compose([f"cache_dir={tmp_path}", "jax_cache.kernel_dir=null"]))
        assert kernel_cache.kernel_dir() is None
        enable_compilation_cache(compose([f"cache_dir={tmp_path}"]))
        enable_compilation_cache(compose([f"cache_dir={tmp_path}", "jax_cache.dir=null"]))
        assert kernel_cache.kernel_dir() is None
    finally:
        enable_compilation_cache(compose(["jax_cache.dir=null"]))


def test_a_fresh_process_uses_the_stored_kernel(kdir):
    """Written by this process, read by another one: the same outputs."""
    x, pair = np.arange(7, dtype=np.float32), (np.ones(2, np.int32), np.arange(5, dtype=np.int32))
    want = np.asarray(kernel_cache.call(_toy, "toy", (x, pair), {"scale": 6})[0])
    code = ("import sys, numpy as np; sys.path.insert(0, %r)\n"
            "from convsynth_jax import kernel_cache\nimport test_kernel_cache as t\n"
            "kernel_cache.set_kernel_dir(%r)\n"
            "import jax\n"
            "def boom(*a, **k): raise SystemExit('compiled again')\n"
            "jax.jit = boom\n"
            "x = np.arange(7, dtype=np.float32); pair = (np.ones(2, np.int32), np.arange(5, dtype=np.int32))\n"
            "np.save(sys.argv[1], np.asarray(kernel_cache.call(t._toy, 'toy', (x, pair), {'scale': 6})[0]))\n"
            ) % (str(REPO / "tests"), str(kdir))
    out = kdir.parent / "out.npy"
    env = dict(os.environ, PYTHONPATH=str(REPO))
    r = subprocess.run([sys.executable, "-c", code, str(out)], env=env, capture_output=True, text=True, cwd=str(REPO))
    assert r.returncode == 0, r.stderr[-2000:]
    np.testing.assert_array_equal(np.load(out), want)


# the set-up of a fresh process running the hub-graph search with the persistent compilation cache on
_SCRIPT_SETUP = """
import sys, numpy as np, jax
sys.path.insert(0, {tests!r})
jax.config.update("jax_compilation_cache_dir", {jc!r})
jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
from convsynth_jax import kernel_cache
from convsynth_jax.search import beam
from convsynth_jax.search.constraints import build_constraints
from convsynth_jax.search.params import SearchParams
from test_search_beam_kernel import FPS, hub_graph, input_from_clip
kernel_cache.set_kernel_dir(sys.argv[1])
g, audio = hub_graph(np.random.default_rng(4))
own, par = input_from_clip(audio, "c4", 40)
cfg = SearchParams(beam_size=16, max_candidates=64, max_degree=24, retry_temperatures=[], retry_beam_size=0)
"""

_SEARCH = _SCRIPT_SETUP + """
res = beam.beam_search(g, build_constraints(own, par, 40, FPS, cfg), cfg, seed=4)
np.save(sys.argv[2], np.asarray(res.path if res.success else [-1]))
"""


def _hub_search_path():
    """The jitted search's path on the scripts' hub graph (-1 when it fails)."""
    g, audio = hub_graph(np.random.default_rng(4))
    own, par = input_from_clip(audio, "c4", 40)
    cfg = SearchParams(beam_size=16, max_candidates=64, max_degree=24, retry_temperatures=[], retry_beam_size=0)
    res = beam_search(g, build_constraints(own, par, 40, FPS, cfg), cfg, seed=4)
    return res.path if res.success else np.array([-1])


def test_stored_kernels_with_the_persistent_compilation_cache(tmp_path):
    """With JAX's persistent compilation cache on (as in every task): a kernel folder written by one
    process, a second folder written by another process after the first populated the compilation
    cache and read back by a fresh process give the jitted search's path (a folder written with an
    empty compilation cache read by a fresh process: test_a_fresh_process_uses_the_stored_kernel). (A stored executable
    that came out of the compilation cache lost its compiled functions on this backend: the third
    process failed with "Function ... not found" before kernels were compiled afresh for storing.)"""
    want = _hub_search_path()
    code = _SEARCH.format(tests=str(REPO / "tests"), jc=str(tmp_path / "jax_cache"))
    env = dict(os.environ, PYTHONPATH=str(REPO))
    for k, folder in enumerate(["k1", "k2", "k2"]):   # the third process failed before the fix
        out = tmp_path / f"path{k}.npy"
        r = subprocess.run([sys.executable, "-c", code, str(tmp_path / folder), str(out)], env=env,
                           capture_output=True, text=True, cwd=str(REPO))
        assert r.returncode == 0, r.stderr[-2000:]
        np.testing.assert_array_equal(np.load(out), want)


_BROKEN = _SCRIPT_SETUP + """
cons = build_constraints(own, par, 40, FPS, cfg)
if sys.argv[3] == "plant":   # store the program as the compilation cache returns it (it cannot run)
    import contextlib
    kernel_cache._fresh_compilation = contextlib.nullcontext
    real, kernel_cache._write = kernel_cache._write, lambda *a: None
    beam.beam_search(g, cons, cfg, seed=4)        # compiled into the persistent cache, not stored
    kernel_cache._LOADED.clear()
    kernel_cache._write = real
    beam.beam_search(g, cons, cfg, seed=4)        # out of the persistent cache, stored
else:
    res = beam.beam_search(g, cons, cfg, seed=4)
    np.save(sys.argv[2], np.asarray(res.path if res.success else [-1]))
"""


def test_a_stored_kernel_that_does_not_run_is_compiled_again(tmp_path):
    """A complete, checksummed file whose program fails when run (here: written from an executable the
    persistent compilation cache returned) is replaced: the search still gives the jitted path."""
    want = _hub_search_path()
    code = _BROKEN.format(tests=str(REPO / "tests"), jc=str(tmp_path / "jax_cache"))
    env = dict(os.environ, PYTHONPATH=str(REPO))
    kdir = tmp_path / "k"
    for k, mode in enumerate(["plant", "run", "run"]):
        out = tmp_path / f"path{k}.npy"
        r = subprocess.run([sys.executable, "-c", code, str(kdir), str(out), mode], env=env, capture_output=True,
                           text=True, cwd=str(REPO))
        assert r.returncode == 0, r.stderr[-2000:]
        if mode == "run":
            np.testing.assert_array_equal(np.load(out), want)
        if k == 1:
            assert "does not run" in r.stderr


@pytest.mark.parametrize("source", ["synthetic", "bandai2"])
def test_graph_construction_through_stored_kernels_equals_the_jitted_one(kdir, source, request):
    """The construction's kernels (forward kinematics, root-relative features, pivots, cost tiles) are
    stored too (a second bandai2 construction skips their tracing); the graph built through
    the stored executables, written by this process and then read back, is the jitted one exactly, on
    random clips and on real Bandai-Namco 2 clips (../shared; skipped without it)."""
    from convsynth_jax.graph import build_database, build_graph
    from convsynth_jax.graph.database import bvh_folder_clips
    from convsynth_jax.graph.params import GraphParams
    from test_graph_build import random_clips

    if source == "bandai2":
        clips = bvh_folder_clips(request.getfixturevalue("bandai_dir"), "*wave-both-hands_normal_00[1-4].bvh")
    else:
        clips = random_clips(11)
    old = kernel_cache.kernel_dir()
    kernel_cache.set_kernel_dir(None)
    want = build_graph(build_database(clips), GraphParams())
    kernel_cache.set_kernel_dir(old)
    first = build_graph(build_database(clips), GraphParams())          # compiled and written
    names = {p.name.split("-")[0] for p in _files(kdir)}
    assert {"fk", "root_relative", "farthest_point", "masked_tile_costs"} <= names
    kernel_cache._LOADED.clear()
    again = build_graph(build_database(clips), GraphParams())          # read back from the files
    for g in (first, again):
        for field in ("indptr", "indices", "cost", "synthetic", "clip", "frame"):
            np.testing.assert_array_equal(getattr(g, field), getattr(want, field))
        assert g.meta["threshold"] == want.meta["threshold"]


def test_compiled_kernel_called_from_threads(kdir):
    """:func:`kernel_cache.compiled` loads or compiles once under a lock; threads calling it at once
    get the jitted kernel's outputs."""
    from concurrent.futures import ThreadPoolExecutor

    x, pair = np.arange(6, dtype=np.float32), (np.ones(3, np.int32), np.arange(4, dtype=np.int32))
    want = np.asarray(_toy(x, pair, scale=2)[0])
    with ThreadPoolExecutor(4) as ex:
        fs = list(ex.map(lambda _: kernel_cache.compiled(_toy, "toy", (x, pair), {"scale": 2}), range(8)))
    assert len(_files(kdir)) == 1
    for f in fs:
        np.testing.assert_array_equal(np.asarray(f(x + 1, pair)[0]), np.asarray(_toy(x + 1, pair, scale=2)[0]))
    np.testing.assert_array_equal(np.asarray(fs[0](x, pair)[0]), want)
