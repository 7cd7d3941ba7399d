"""Per-session work over processes (convsynth_jax.parallel): the same bytes and annotations as in one
process, failures raised, and the worker count's rules."""
import filecmp
import functools
import pickle

import pytest

from convsynth_jax.annotate.params import AnnotateParams
from convsynth_jax.annotate.pipeline import annotate_corpus
from convsynth_jax.data import make_synthetic_corpus
from convsynth_jax.io import load_corpus
from convsynth_jax.parallel import ENV, ordered_map, resolve_workers

SMALL = {"num_sessions": 3, "session_seconds": 20.0}


@pytest.fixture(scope="module")
def corpora(tmp_path_factory):
    root = tmp_path_factory.mktemp("par")
    return make_synthetic_corpus(root / "one", SMALL, workers=1), make_synthetic_corpus(root / "two", SMALL, workers=2)


def test_generation_same_bytes_with_worker_processes(corpora):
    one, two = corpora
    names = sorted(p.name for p in one.iterdir())
    assert names == sorted(p.name for p in two.iterdir()) and len(names) == 3 * 6 + 3
    match, mismatch, errors = filecmp.cmpfiles(one, two, names, shallow=False)
    assert mismatch == [] and errors == [] and len(match) == len(names)


def test_annotation_same_with_worker_processes(corpora):
    corpus = load_corpus(corpora[0])
    serial = annotate_corpus(corpus, AnnotateParams(), 30.0, progress=False, workers=1)
    pooled = annotate_corpus(corpus, AnnotateParams(), 30.0, progress=False, workers=2)
    assert list(serial) == list(pooled) == [s.name for s in corpus.sessions]
    for name in serial:
        for role in serial[name]:
            a, b = serial[name][role], pooled[name][role]
            assert len(a.events) > 0 and len(a.segments) > 0
            assert pickle.dumps(a.events) == pickle.dumps(b.events)
            assert pickle.dumps(a.segments) == pickle.dumps(b.segments)
            assert pickle.dumps(a.own) == pickle.dumps(b.own)
            assert (a.motion.rotations == b.motion.rotations).all()


def test_failure_in_a_worker_is_raised():
    # resolve_workers(0, n) raises in the worker process; the error reaches the caller
    with pytest.raises(ValueError, match="at least 1"):
        ordered_map(functools.partial(resolve_workers, 0), [1, 2], workers=2, min_items=1)


def test_worker_count_rules(monkeypatch):
    monkeypatch.delenv(ENV, raising=False)
    assert resolve_workers(None, 2) == 1            # fewer items than min_items: no pool
    assert resolve_workers(8, 3) == 3               # never more processes than items
    assert resolve_workers(1, 10) == 1
    monkeypatch.setenv(ENV, "2")
    assert resolve_workers(None, 10) == 2
    monkeypatch.setenv(ENV, "two")
    with pytest.raises(ValueError, match=ENV):
        resolve_workers(None, 10)
    with pytest.raises(ValueError, match="at least 1"):
        resolve_workers(0, 10)
