"""The JAX persistent compilation cache is enabled at the task boundary.
No timing assertions: only that a task run populates ``<cache_dir>/jax_cache`` and that the config
key turns it off or moves it."""
import os
import subprocess
import sys
from pathlib import Path

from conftest import TEST_DATA

REPO = Path(__file__).resolve().parent.parent
BVH = TEST_DATA / "dataset-2_raise-up-right-hand_normal_016.bvh"


def _run(tmp_path, *overrides):
    env = dict(os.environ, PYTHONPATH=str(REPO), CONVSYNTH_CACHE=str(tmp_path / "cache"))
    env.pop("CONVSYNTH_JAX_CACHE", None)   # the default place, not the test run's shared folder
    r = subprocess.run([sys.executable, "-m", "convsynth_jax.config", "task=inspect", f"path={BVH}",
                        f"hydra.run.dir={tmp_path / 'out'}", *overrides], env=env, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-2000:]


def _entries(d: Path) -> list:
    return [p for p in d.rglob("*") if p.is_file()] if d.exists() else []


def test_task_run_populates_the_compilation_cache(tmp_path):
    _run(tmp_path)
    assert _entries(tmp_path / "cache" / "jax_cache"), "a task run wrote no compiled kernels to <cache_dir>/jax_cache"


def test_the_environment_variable_moves_the_default_folder(tmp_path, monkeypatch):
    """``CONVSYNTH_JAX_CACHE`` (one compilation cache for every run, e.g. a whole test run) replaces the
    default ``<cache_dir>/jax_cache``; an explicit ``jax_cache.dir`` still wins."""
    from convsynth_jax.config import compose

    monkeypatch.setenv("CONVSYNTH_JAX_CACHE", str(tmp_path / "shared"))
    assert compose([f"cache_dir={tmp_path}"]).jax_cache.dir == str(tmp_path / "shared")
    assert compose([f"cache_dir={tmp_path}", "jax_cache.dir=null"]).jax_cache.dir is None
    monkeypatch.delenv("CONVSYNTH_JAX_CACHE")
    assert compose([f"cache_dir={tmp_path}"]).jax_cache.dir == f"{tmp_path}/jax_cache"


def test_compilation_cache_can_be_moved_and_disabled(tmp_path):
    _run(tmp_path, f"jax_cache.dir={tmp_path / 'elsewhere'}")
    assert _entries(tmp_path / "elsewhere")
    assert not (tmp_path / "cache" / "jax_cache").exists()
    _run(tmp_path / "off", "jax_cache.dir=null")
    assert not (tmp_path / "off" / "cache" / "jax_cache").exists()


def test_enable_and_disable_within_one_process(tmp_path, monkeypatch):
    import jax
    import jax.numpy as jnp

    from convsynth_jax.config import compose
    from convsynth_jax.tasks.common import enable_compilation_cache

    monkeypatch.delenv("CONVSYNTH_JAX_CACHE", raising=False)   # the default place, under cache_dir
    try:
        assert enable_compilation_cache(compose([f"cache_dir={tmp_path}"])) == (tmp_path / "jax_cache").resolve()
        jax.jit(lambda x: x * 3.5 + 1.25)(jnp.ones(7)).block_until_ready()  # a kernel no other test compiles
        n = len(_entries(tmp_path / "jax_cache"))
        assert n > 0
        assert enable_compilation_cache(compose([f"cache_dir={tmp_path}", "jax_cache.dir=null"])) is None
        jax.jit(lambda x: x * 5.5 - 2.25)(jnp.ones(9)).block_until_ready()
        assert len(_entries(tmp_path / "jax_cache")) == n
    finally:
        enable_compilation_cache(compose(["jax_cache.dir=null"]))
