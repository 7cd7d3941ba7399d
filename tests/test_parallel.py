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


def test_main_module_that_cannot_be_imported_again(monkeypatch):
    import sys
    import types
    import warnings

    from convsynth_jax import parallel

    monkeypatch.setattr(parallel, "_WARNED", set())
    stdin = types.ModuleType("__main__")
    stdin.__file__ = "<stdin>"          # python - <<EOF
    monkeypatch.setitem(sys.modules, "__main__", stdin)
    assert "<stdin>" in parallel.spawn_unavailable(len)
    with pytest.warns(RuntimeWarning, match="in this process"):
        assert ordered_map(abs, [-1, -2, 3], workers=3, min_items=1) == [1, 2, 3]
    with warnings.catch_warnings():      # one warning per reason and process
        warnings.simplefilter("error", RuntimeWarning)
        assert ordered_map(abs, [-4, 5], workers=2, min_items=1) == [4, 5]
        assert ordered_map(abs, [-6], workers=1) == [6]   # workers=1: in this process, never a warning
    no_file = types.ModuleType("__main__")   # python -c, an interactive session: library functions spawn fine
    monkeypatch.setitem(sys.modules, "__main__", no_file)
    assert parallel.spawn_unavailable(abs) is None
    fn = functools.partial(lambda x: x, 1)
    fn.func.__module__ = "__main__"      # ... but a function of that main module cannot be found there
    assert "without a file" in parallel.spawn_unavailable(functools.partial(fn))


# a script read from standard input: the worker processes could not import it again
STDIN_SCRIPT = """
import sys, warnings
from convsynth_jax.data import make_synthetic_corpus
with warnings.catch_warnings(record=True) as seen:
    warnings.simplefilter("always")
    out = make_synthetic_corpus(sys.argv[1], {"num_sessions": 2, "session_seconds": 10.0}, workers=2)
print(len(list(out.iterdir())), sum(issubclass(w.category, RuntimeWarning) and "in this process" in str(w.message)
                                    for w in seen))
"""


def test_script_on_standard_input_generates_the_corpus(tmp_path):
    import os
    import subprocess
    import sys

    env = {**os.environ, "CONVSYNTH_WORKERS": "2"}
    run = subprocess.run([sys.executable, "-", str(tmp_path / "c")], input=STDIN_SCRIPT, text=True,
                         capture_output=True, env=env, cwd=tmp_path, timeout=300)
    assert run.returncode == 0, run.stderr[-3000:]
    files, warned = run.stdout.split()
    assert int(files) == 2 * 6 + 3 and int(warned) == 1
