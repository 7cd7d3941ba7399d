"""Caches keyed by content, not names: a corpus edited in place (a BVH's motion changed, file names,
size and modification time unchanged) gives, on the same cache folder, exactly the leave-one-out
cases of a fresh cache folder; a motion graph fitted on other motion with the same clip names is built
again, not read from the cache; fingerprints see file bytes and the code."""
from __future__ import annotations

import copy
import dataclasses
import os
import re
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from convsynth_jax.fingerprint import FOUNDATION, code_fingerprint, content_digest, file_digest

REPO = Path(__file__).resolve().parent.parent


def _edit_in_place(path: Path) -> None:
    """Reverse the order of a BVH's frames: other motion, same bytes count; the modification time is
    set back, so only the content (and the inode's change time) says it changed."""
    st = path.stat()
    lines = path.read_bytes().split(b"\n")
    first = next(i for i, ln in enumerate(lines) if ln.startswith(b"Frame Time")) + 1
    last = max(i for i, ln in enumerate(lines) if ln.strip())
    lines[first:last + 1] = lines[first:last + 1][::-1]
    path.write_bytes(b"\n".join(lines))
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert path.stat().st_size == st.st_size and path.stat().st_mtime_ns == st.st_mtime_ns


def test_file_digest_sees_an_edit_that_keeps_size_and_mtime(tmp_path):
    f = tmp_path / "a.bvh"
    f.write_bytes(b"HIERARCHY\nMOTION\nFrame Time: 0.0333\n1 2 3\n4 5 6\n7 8 9\n")
    before = file_digest(f)
    assert file_digest(f) == before
    _edit_in_place(f)
    assert file_digest(f) != before


def test_content_digest_sees_array_content():
    a = {"m": np.arange(2000, dtype=np.float32), "name": "session01_main-agent"}
    b = copy.deepcopy(a)
    assert content_digest(a) == content_digest(b)
    b["m"][1500] += 1  # past what a repr would print
    assert content_digest(a) != content_digest(b)
    assert content_digest(np.zeros(3, np.float32)) != content_digest(np.zeros(3, np.float64))


def test_foundation_is_the_layers_below_io():
    """code_fingerprint(parts) hashes FOUNDATION as the modules every layer may import: it must list
    exactly the modules of the import-linter layers below io."""
    text = (REPO / "pyproject.toml").read_text()
    layers = re.search(r"layers = \[(.*?)\]", text, re.S).group(1)
    below_io = layers.split('"convsynth_jax.io",')[1]
    modules = set(re.findall(r"convsynth_jax\.(\w+)", below_io))
    assert modules == set(FOUNDATION)
    assert code_fingerprint("io", "annotate") != code_fingerprint("io", "annotate", "graph") != code_fingerprint()


def _corpus_copy(tiny_corpus_dir, dest: Path) -> Path:
    shutil.copytree(tiny_corpus_dir, dest)
    return dest


def test_corpus_fingerprint_follows_content_not_place(tiny_corpus_dir, tmp_path):
    from convsynth_jax.annotate.cache import annotation_key
    from convsynth_jax.annotate.params import AnnotateParams
    from convsynth_jax.io import load_corpus

    a = _corpus_copy(tiny_corpus_dir, tmp_path / "a")
    fp = load_corpus(a).fingerprint()
    key = annotation_key(load_corpus(a), AnnotateParams(), 30.0)
    assert load_corpus(tiny_corpus_dir).fingerprint() == fp  # a copy elsewhere: same content
    _edit_in_place(a / "session02_main-agent.bvh")
    assert load_corpus(a).fingerprint() != fp
    assert annotation_key(load_corpus(a), AnnotateParams(), 30.0) != key


def test_an_edited_file_re_annotates_its_session_only(tiny_corpus_dir, tmp_path, monkeypatch):
    """The annotation cache is per session: after one BVH is edited in place, only its session is
    annotated again; the others are read from the cache."""
    from convsynth_jax.annotate import cache as ann_cache
    from convsynth_jax.annotate.params import AnnotateParams
    from convsynth_jax.io import load_corpus

    corpus_dir = _corpus_copy(tiny_corpus_dir, tmp_path / "c")
    annotated = []

    def stand_in(corpus, params, fps, progress=True, workers=None):
        annotated.append([s.name for s in corpus.sessions])
        return {s.name: (s.name, len(annotated)) for s in corpus.sessions}

    monkeypatch.setattr(ann_cache, "annotate_corpus", stand_in)
    first = ann_cache.annotate_corpus_cached(load_corpus(corpus_dir), AnnotateParams(), 30.0, tmp_path / "cache")
    _edit_in_place(corpus_dir / "session02_main-agent.bvh")
    again = ann_cache.annotate_corpus_cached(load_corpus(corpus_dir), AnnotateParams(), 30.0, tmp_path / "cache")
    assert annotated == [["session01", "session02", "session03"], ["session02"]]
    assert again == {**first, "session02": ("session02", 2)}


def test_graph_cache_is_keyed_by_the_clips_content(tiny_annotations, tmp_path):
    """Fitting on other motion with the same clip names (e.g. another corpus whose sessions are also
    named session01...) builds the graph again instead of returning the cached one."""
    from convsynth_jax.config import compose, to_params
    from convsynth_jax.evaluation.loo import training_clips
    from convsynth_jax.systems.base import make_system

    params = to_params(compose(["corpus=synthetic_tiny", "progress=false"]))
    system = make_system(params, params.system)
    held_out = sorted(tiny_annotations)[0]
    char = tiny_annotations[held_out]["main-agent"].character
    clips = training_clips(tiny_annotations, held_out, char)
    cache = tmp_path / "graphs"
    first = system.fit(clips, char, "all", cache)
    other = []
    for c in clips:  # other motion, same names: the frames of each clip's second half reversed
        m = c.motion
        half = m.num_frames // 2
        rev = np.concatenate([np.arange(half), np.arange(m.num_frames - 1, half - 1, -1)])
        other.append(dataclasses.replace(c, motion=dataclasses.replace(
            m, rotations=np.asarray(m.rotations)[rev], translations=np.asarray(m.translations)[rev])))
    again = system.fit(other, char, "all", cache)
    fresh = system.fit(other, char, "all", None)
    assert again.graph.num_states == fresh.graph.num_states
    np.testing.assert_array_equal(np.asarray(again.graph.indices), np.asarray(fresh.graph.indices))
    np.testing.assert_array_equal(np.asarray(again.graph.cost), np.asarray(fresh.graph.cost))
    assert not (np.array_equal(np.asarray(first.graph.indptr), np.asarray(fresh.graph.indptr))
                and np.array_equal(np.asarray(first.graph.cost), np.asarray(fresh.graph.cost)))


def _loo_cases(corpus: Path, cache: Path, out: Path) -> tuple[pd.DataFrame, dict]:
    from convsynth_jax.config import compose, run_task

    summary = run_task(compose(["task=loo", "corpus=genea", f"corpus.root={corpus}", f"cache_dir={cache}",
                                "progress=false", "loo.max_windows=1", "fold=0", "condition=none",
                                "jax_cache.kernel_dir=null"]), out)
    df = pd.read_csv(out / "cases.csv")
    return df.drop(columns=[c for c in df.columns if "seconds" in c]), summary


@pytest.mark.slow
def test_corpus_edited_in_place_gives_a_fresh_cache_s_cases(tiny_corpus_dir, tmp_path):
    """A GENEA-layout corpus, leave-one-out fold 0; one training BVH edited in place (names, size and
    modification time unchanged) and the fold run again on the same cache folder (annotations, graphs,
    results store): its cases are exactly a fresh cache folder's, and differ from before the edit."""
    corpus = _corpus_copy(tiny_corpus_dir, tmp_path / "corpus")
    before, _ = _loo_cases(corpus, tmp_path / "cache", tmp_path / "before")
    _edit_in_place(corpus / "session02_main-agent.bvh")
    same, summary = _loo_cases(corpus, tmp_path / "cache", tmp_path / "same")
    fresh, _ = _loo_cases(corpus, tmp_path / "fresh_cache", tmp_path / "fresh")
    assert not summary["resumed"]
    pd.testing.assert_frame_equal(same, fresh)
    assert not before.equals(fresh)
