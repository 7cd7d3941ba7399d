"""Caches shared by processes started together: the synthetic corpus, the
annotation cache, the stored kernels and JAX's compilation cache are each computed once and never
read half-written. The full command-line reproduction (4 ``convsynth task=cooccurrence`` and a joblib
multirun of 4) is experiments/bench/parallel_cache.py."""
from __future__ import annotations

from convsynth_jax.testing.cache_race import cache_report, start_together

# a small corpus: the race is in how it is written and found, not in its size
GENERATOR = {"seed": 1, "num_sessions": 2, "session_seconds": 10.0, "calibrate_rates": False,
             "quota_planting": False, "glitches_per_minute": 0.0}


def test_four_processes_on_one_empty_cache_compute_each_entry_once(tmp_path, monkeypatch):
    monkeypatch.delenv("CONVSYNTH_JAX_CACHE", raising=False)   # their own <cache>/jax_cache, empty
    cache = tmp_path / "cache"
    results = start_together({"cache": str(cache), "barrier": str(tmp_path / "barrier"), "out": str(tmp_path / "out"),
                              "generator": GENERATOR}, processes=4)
    # each entry computed by exactly one process
    for what in ("corpus", "annotate", "kernel"):
        assert sum(r["counts"][what] for r in results) == 1, (what, [r["counts"] for r in results])
    # identical outputs: the same corpus bytes, annotation and kernel result in every process
    assert len(results[0]["files"]) == 2 * 2 * 3
    for r in results[1:]:
        assert r["files"] == results[0]["files"]
        assert r["annotation"] == results[0]["annotation"]
        assert r["kernel"] == results[0]["kernel"]
    # every cache file reads back intact, and no temporary file or old copy is left visible
    import pickle

    from convsynth_jax import kernel_cache

    files = sorted((cache / "loo_cache").glob("annotations_*.pkl"))   # one per session
    assert len(files) == len(results[0]["annotation"])
    assert sorted(map(str, (pickle.loads(f.read_bytes()) for f in files))) == \
        sorted(map(str, results[0]["annotation"].values()))
    (kfile,) = (cache / "jax_kernels").glob("race_kernel-*.jaxexe")
    key = kfile.name[len("race_kernel-"):-len(".jaxexe")]
    kernel_cache.set_kernel_dir(kfile.parent)
    try:
        assert kernel_cache._read(kfile, key) is not None
    finally:
        kernel_cache.set_kernel_dir(None)
    report = cache_report(cache)   # JAX's entries decompress, the pickles load, no temporary is left
    assert report["jax_entries"][0] > 0 and report["annotations"][0] == len(files), report
    assert report["jax_entries"][1] == report["annotations"][1] == report["leftover_temporaries"] == 0, report
    # JAX's own lock guards its folder (jax_cache.max_size_bytes); our entries have theirs
    assert (cache / "jax_cache" / ".lockfile").exists()


def test_cache_report_counts_unreadable_entries_and_leftover_temporaries(tmp_path):
    import pickle

    (tmp_path / "loo_cache").mkdir()
    (tmp_path / "loo_cache" / "annotations_a.pkl").write_bytes(pickle.dumps({"a": 1}))
    (tmp_path / "loo_cache" / "annotations_b.pkl").write_bytes(pickle.dumps({"b": 2})[:-3])   # cut short
    (tmp_path / "loo_cache" / ".annotations_c.pkl.tmp123").write_bytes(b"")
    (tmp_path / "loo_cache" / "annotations_a.pkl.lock").write_bytes(b"")
    report = cache_report(tmp_path)
    assert report["annotations"] == [2, 1] and report["graphs"] == [0, 0] and report["jax_entries"] == [0, 0]
    assert report["leftover_temporaries"] == 1
