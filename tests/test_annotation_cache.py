"""The on-disk annotation cache is keyed by the corpus's contents, not only its folder."""
import os

from convsynth_jax.annotate import cache as ann_cache
from convsynth_jax.config import default_params
from convsynth_jax.tasks.common import open_corpus


def test_cache_is_not_reused_after_the_corpus_files_change(tmp_path, monkeypatch):
    """A corpus regenerated in the same folder (here: one transcript rewritten) must be annotated
    again; before, the cache key was the folder path alone and the old annotations came back."""
    p = default_params(["corpus=synthetic_tiny", f"cache_dir={tmp_path}", "progress=false"])
    corpus = open_corpus(p)
    calls = []

    def fake_annotate(corpus, params, fps, progress=True, workers=None):
        calls.append(1)
        return {s.name: {"n": len(calls)} for s in corpus.sessions}

    monkeypatch.setattr(ann_cache, "annotate_corpus", fake_annotate)
    cdir = tmp_path / "ann"
    first = ann_cache.annotate_corpus_cached(corpus, p.annotate, 30.0, cdir, progress=False)
    again = ann_cache.annotate_corpus_cached(corpus, p.annotate, 30.0, cdir, progress=False)
    names = [s.name for s in corpus.sessions]
    assert first == again == {n: {"n": 1} for n in names} and len(calls) == 1  # unchanged corpus: the cache is used
    f = corpus.sessions[0].participants[0].transcript_path
    st = os.stat(f)
    f.write_text(f.read_text() + "\n")
    os.utime(f, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
    changed = ann_cache.annotate_corpus_cached(corpus, p.annotate, 30.0, cdir, progress=False)
    # the edited session is annotated again, the others are read
    assert changed == {n: {"n": 2 if n == corpus.sessions[0].name else 1} for n in names} and len(calls) == 2


def test_seeded_cache_folder_serves_a_task_without_annotating(tiny_corpus_dir, tiny_cache_dir, monkeypatch):
    """The test fixture ``tiny_cache_dir`` seeds the annotation where tasks read it: a task's corpus
    step on a seeded folder annotates nothing (it once copied the file beside ``loo_cache``, and every
    task-running test annotated the tiny corpus again)."""
    from convsynth_jax.tasks.common import annotated_corpus

    def no_annotation(*a, **k):
        raise AssertionError("annotated again")

    monkeypatch.setattr(ann_cache, "annotate_corpus", no_annotation)
    p = default_params(["corpus=synthetic_tiny", f"corpus.root={tiny_corpus_dir}",
                        f"cache_dir={tiny_cache_dir('seeded')}", "progress=false"])
    _, ann = annotated_corpus(p)
    assert set(ann) == {s.name for s in open_corpus(p).sessions}
