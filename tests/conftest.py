"""Shared test fixtures. Real data lives in ../shared/data beside the checkout; tests that need it
skip cleanly when it is absent (e.g. on a machine without the shared folder)."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
TEST_DATA = Path(__file__).resolve().parent / "data"
SHARED = Path(os.environ.get("CONVSYNTH_SHARED", REPO.parent / "shared")).resolve()
SHARED_DATA = SHARED / "data"
# pytest-xdist already keeps every core busy: per-session work runs in the test's own process unless a
# test asks for worker processes (tests/test_parallel.py).
os.environ.setdefault("CONVSYNTH_WORKERS", "1")

# XLA's CPU code generation for the suite: the older LLVM fusion emitters instead of the default MLIR ones.
# Compiling is about half of the suite's time, and this flag takes about a third off it (docs/testing.md);
# tests/test_codegen.py checks that kernels give the same results under XLA's default. Set before any JAX
# backend starts (XLA reads XLA_FLAGS then); the pytest-xdist workers and the processes tests start
# inherit it. A flag of the caller's own for the emitters is kept.
SUITE_XLA_FLAG = "--xla_cpu_use_fusion_emitters=false"
if "xla_cpu_use_fusion_emitters" not in os.environ.get("XLA_FLAGS", ""):
    os.environ["XLA_FLAGS"] = f"{os.environ.get('XLA_FLAGS', '')} {SUITE_XLA_FLAG}".strip()


def pytest_configure(config):
    """One JAX persistent compilation cache for the whole test run (``CONVSYNTH_JAX_CACHE``, which the
    config's ``jax_cache.dir`` defaults to when set): the pytest-xdist workers, the processes tests
    start and the tasks they run compile a kernel once, not once per process. Set in the controlling
    process before the workers start, so they inherit it; a folder of the caller's own is kept."""
    if os.environ.get("PYTEST_XDIST_WORKER") or "CONVSYNTH_JAX_CACHE" in os.environ:
        return
    import tempfile

    config._convsynth_jax_cache = tempfile.mkdtemp(prefix="convsynth-tests-")
    os.environ["CONVSYNTH_JAX_CACHE"] = os.path.join(config._convsynth_jax_cache, "jax_cache")


def pytest_unconfigure(config):
    folder = getattr(config, "_convsynth_jax_cache", None)
    if folder:
        import shutil

        shutil.rmtree(folder, ignore_errors=True)
        os.environ.pop("CONVSYNTH_JAX_CACHE", None)


def _use_session_compilation_cache():
    folder = os.environ.get("CONVSYNTH_JAX_CACHE")
    if folder:
        import jax

        from convsynth_jax import kernel_cache

        if jax.config.jax_compilation_cache_dir != str(Path(folder).resolve()) or kernel_cache.kernel_dir() is not None:
            kernel_cache.enable_compilation_cache(kernel_cache.JaxCacheParams(dir=folder))


@pytest.fixture(scope="session", autouse=True)
def _compilation_cache_from_the_start():
    """The run's compilation cache from the first fixture on: module and session fixtures (which pytest
    sets up before a test's function-scoped fixtures) compile into it too."""
    _use_session_compilation_cache()
    yield


@pytest.fixture(autouse=True)
def _session_compilation_cache():
    """Kernels that tests compile in their own process go to the run's compilation cache too; a test
    that moved or disabled the cache (a task run points JAX at its ``jax_cache.dir``) gets it back for
    the next test."""
    _use_session_compilation_cache()
    yield


@pytest.fixture(scope="session")
def librosa_ready(_shared_dir):
    """librosa, imported with its numba kernels compiled. A fresh environment compiles them on first use
    (about 20 s of CPU) and caches them on disk: the first pytest-xdist worker to get here compiles them
    under a file lock, the others wait and load them from the cache instead of compiling them too."""
    from filelock import FileLock

    with FileLock(str(_shared_dir / "librosa.lock")):
        import librosa.onset  # noqa: F401  (compiles or loads the numba kernels)


def shared_path(*parts: str) -> Path:
    """Path under ../shared/data, or skip the calling test if it does not exist."""
    p = SHARED_DATA.joinpath(*parts)
    if not p.exists():
        pytest.skip(f"shared data not available: {p}")
    return p


@pytest.fixture
def bandai_dir() -> Path:
    return shared_path("bandai2", "bvh")


@pytest.fixture
def speech_dir() -> Path:
    return shared_path("speech")


@pytest.fixture(scope="session")
def _shared_dir(tmp_path_factory) -> Path:
    """A folder shared by every pytest-xdist worker of this run (this run's own temporary folder
    without xdist): the expensive session set-ups below are built in it once, not once per worker."""
    base = tmp_path_factory.getbasetemp()
    return base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base


def _build_once(shared: Path, name: str, build) -> Path:
    """``shared/name``, built by ``build(path)`` by the first worker that gets here; the others wait
    for it under a file lock and reuse it. A build that fails leaves no marker, so the next worker
    tries again (and fails the same way, with its own traceback)."""
    from filelock import FileLock

    target = shared / name
    with FileLock(str(shared / f"{name}.lock")):
        if not (shared / f"{name}.done").exists():
            if target.exists():
                import shutil

                shutil.rmtree(target)
            target.mkdir(parents=True)
            build(target)
            (shared / f"{name}.done").touch()
    return target


@pytest.fixture(scope="session")
def tiny_corpus_dir(_shared_dir) -> Path:
    """A tiny synthetic dyadic corpus generated once per test run (shared by the xdist workers)."""
    from convsynth_jax.config import compose
    from convsynth_jax.data import make_synthetic_corpus

    def build(out: Path) -> None:
        make_synthetic_corpus(out / "synthetic_tiny", compose(["corpus=synthetic_tiny"]).corpus.generator)

    return _build_once(_shared_dir, "tiny_corpus", build) / "synthetic_tiny"


@pytest.fixture(scope="session")
def _tiny_annotation_cache(tiny_corpus_dir, _shared_dir) -> Path:
    """A cache folder holding the tiny corpus's annotation (default parameters, 30 fps), computed once
    per test run; ``tiny_cache_dir`` copies it into fresh cache folders."""
    from convsynth_jax.annotate.cache import annotate_corpus_cached
    from convsynth_jax.annotate.params import AnnotateParams
    from convsynth_jax.io import load_corpus

    def build(cache: Path) -> None:
        annotate_corpus_cached(load_corpus(tiny_corpus_dir), AnnotateParams(), 30.0, cache, progress=False)

    return _build_once(_shared_dir, "tiny_annotation_cache", build)


@pytest.fixture(scope="session")
def tiny_annotations(_tiny_annotation_cache, tiny_corpus_dir) -> dict:
    """The tiny corpus annotated once per session (default parameters, 30 fps): session -> role ->
    ParticipantAnnotation. Shared: tests that change it must copy it first (``copy.deepcopy``)."""
    from convsynth_jax.annotate.cache import annotate_corpus_cached
    from convsynth_jax.annotate.params import AnnotateParams
    from convsynth_jax.io import load_corpus

    return annotate_corpus_cached(load_corpus(tiny_corpus_dir), AnnotateParams(), 30.0, _tiny_annotation_cache,
                                  progress=False)


@pytest.fixture(scope="session")
def tiny_cache_dir(_tiny_annotation_cache, tmp_path_factory):
    """A factory of fresh folders for ``cache_dir=`` that already hold the tiny corpus's annotation
    where tasks look for it (``<cache_dir>/loo_cache``, :func:`convsynth_jax.api.cache_dir`),
    so a task run on the tiny corpus does not annotate it again (everything else starts empty)."""
    import shutil

    def make(name: str = "cache") -> Path:
        out = tmp_path_factory.mktemp(name)
        (out / "loo_cache").mkdir()
        for f in _tiny_annotation_cache.glob("annotations_*.pkl"):
            shutil.copy2(f, out / "loo_cache" / f.name)
        return out

    return make


@pytest.fixture(scope="session")
def main_run(tiny_corpus_dir, tiny_cache_dir, _shared_dir):
    """One run of the main job on the tiny corpus (two leave-one-out windows, Table 2 for k = 2, 3),
    shared by the report and notebook tests (and the xdist workers; read it, never write into it):
    (output folder, summary)."""
    import json

    from convsynth_jax.config import compose, run_task

    def build(out: Path) -> None:
        cache = tiny_cache_dir('main_cache')
        run_task(compose(["corpus=synthetic_tiny", f"corpus.root={tiny_corpus_dir}",
                          f"cache_dir={cache}", "progress=false", "loo.max_windows=2",
                          "task.paper_ks=[2,3]"]), out)
        # its fitted graphs and compiled kernels, for tests that run more of the same (tests/test_study_e2e.py)
        (out / "cache_dir.txt").write_text(str(cache))

    out = _build_once(_shared_dir, "main_run", build)
    return out, json.loads((out / "summary.json").read_text())
