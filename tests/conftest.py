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
def tiny_corpus_dir(tmp_path_factory) -> Path:
    """A tiny synthetic dyadic corpus generated once per test session."""
    from convsynth_jax.config import compose
    from convsynth_jax.data import make_synthetic_corpus

    cfg = compose(["corpus=synthetic_tiny"])
    out = tmp_path_factory.mktemp("tiny_corpus")
    return Path(make_synthetic_corpus(out / "synthetic_tiny", cfg.corpus.generator))


@pytest.fixture(scope="session")
def _tiny_annotation_cache(tiny_corpus_dir, tmp_path_factory) -> Path:
    """A cache folder holding the tiny corpus's annotation (default parameters, 30 fps), computed once
    per test session; ``tiny_cache_dir`` copies it into fresh cache folders."""
    from convsynth_jax.annotate.cache import annotate_corpus_cached
    from convsynth_jax.annotate.params import AnnotateParams
    from convsynth_jax.io import load_corpus

    cache = tmp_path_factory.mktemp("tiny_annotation_cache")
    annotate_corpus_cached(load_corpus(tiny_corpus_dir), AnnotateParams(), 30.0, cache, progress=False)
    return cache


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
    """A factory of fresh cache folders that already hold the tiny corpus's annotation, so a task run
    on the tiny corpus does not annotate it again (everything else in the folder starts empty)."""
    import shutil

    def make(name: str = "cache") -> Path:
        out = tmp_path_factory.mktemp(name)
        for f in _tiny_annotation_cache.glob("annotations_*.pkl"):
            shutil.copy2(f, out / f.name)
        return out

    return make


@pytest.fixture(scope="session")
def main_run(tiny_corpus_dir, tiny_cache_dir, tmp_path_factory):
    """One run of the main job on the tiny corpus (two leave-one-out windows, Table 2 for k = 2, 3),
    shared by the report and notebook tests: (output folder, summary)."""
    from convsynth_jax.config import compose, run_task

    out = tmp_path_factory.mktemp("main")
    s = run_task(compose(["corpus=synthetic_tiny", f"corpus.root={tiny_corpus_dir}", f"cache_dir={tiny_cache_dir('main_cache')}",
                          "progress=false", "loo.max_windows=2", "task.paper_ks=[2,3]"]), out)
    return out, s
