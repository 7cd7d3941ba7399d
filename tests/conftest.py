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
