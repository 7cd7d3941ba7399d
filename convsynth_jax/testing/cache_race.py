"""Several processes started together on one empty cache folder (tests/test_shared_cache.py and
experiments/bench/parallel_cache.py).

``python -m convsynth_jax.testing.cache_race SPEC.json INDEX`` is one such process. ``SPEC.json`` holds
``cache`` (the shared folder), ``barrier`` (a folder: the process writes ``ready-INDEX`` there, then
waits for ``go`` so that all start at once), ``generator`` (the synthetic corpus's generator
parameters) and ``out`` (where the process writes ``result-INDEX.json``). The process

1. opens the synthetic corpus through :func:`convsynth_jax.data.ensure_synthetic_corpus` and reads
   every file of it with the project's readers;
2. annotates it through :func:`convsynth_jax.annotate.cache.annotate_corpus_cached`, with the
   annotator replaced by a cheap stand-in (the cache's locking is under test, not the annotation);
3. calls a small jitted kernel through :mod:`convsynth_jax.kernel_cache` (stored kernels) and another
   directly (JAX's compilation cache), both caches in the shared folder;

and records how many times it computed each entry (generated the corpus, annotated, compiled and
stored the kernel) and a digest of what it read. :func:`start_together` runs N of them and returns
their results; :func:`cache_report` reads every entry of the folder back. Test helper only: no library
module imports it.
"""
from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
import time
from pathlib import Path


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _worker(spec: dict, index: int) -> dict:
    import jax
    import jax.numpy as jnp
    import numpy as np

    from .. import kernel_cache
    from ..annotate import cache as annotation_cache
    from ..data import ensure_synthetic_corpus
    from ..data.synthetic import writer
    from ..io.audio import load_audio
    from ..io.bvh import load_bvh
    from ..io.corpus import load_corpus
    from ..io.transcripts import load_transcript

    counts = {"corpus": 0, "annotate": 0, "kernel": 0}
    make = writer.make_synthetic_corpus

    def counted_make(*a, **k):
        counts["corpus"] += 1
        return make(*a, **k)

    def stand_in_annotate(corpus, params, fps, progress=True, workers=None):
        counts["annotate"] += 1
        time.sleep(0.5)  # long enough for the others to arrive while it computes
        return {s.name: sorted(p.role for p in s.participants) for s in corpus.sessions}

    write = kernel_cache._write

    def counted_write(*a, **k):
        counts["kernel"] += 1
        return write(*a, **k)

    writer.make_synthetic_corpus = counted_make
    annotation_cache.annotate_corpus = stand_in_annotate
    kernel_cache._write = counted_write
    cache = Path(spec["cache"])
    kernel_cache.enable_compilation_cache(kernel_cache.JaxCacheParams(dir=str(cache / "jax_cache"),
                                                                      kernel_dir=str(cache / "jax_kernels")))

    @jax.jit
    def kernel(x):
        return jnp.cumsum(jnp.sin(x) * 2.0)

    barrier = Path(spec["barrier"])
    (barrier / f"ready-{index}").touch()
    deadline = time.monotonic() + 120
    while not (barrier / "go").exists():
        if time.monotonic() > deadline:
            raise TimeoutError("no go signal")
        time.sleep(0.005)

    root = ensure_synthetic_corpus({"name": "synthetic_race", "root": None, "generator": spec["generator"]}, cache)
    corpus = load_corpus(root, layout="genea")
    files = {}
    for s in corpus.sessions:
        for p in s.participants:
            load_bvh(p.motion_path)
            load_audio(p.audio_path)
            load_transcript(p.transcript_path)
            for f in (p.motion_path, p.audio_path, p.transcript_path):
                files[Path(f).name] = _digest(Path(f))
    ann = annotation_cache.annotate_corpus_cached(corpus, None, 30.0, cache / "loo_cache", progress=False)
    x = np.linspace(0.0, 1.0, 64, dtype=np.float32)
    stored = kernel_cache.call(kernel, "race_kernel", (x,))   # through the stored kernels
    direct = jax.jit(lambda v: jnp.cos(v) + 1.0)(x)            # through JAX's compilation cache
    return {"index": index, "counts": counts, "files": files, "annotation": ann,
            "kernel": hashlib.sha256(np.asarray(stored).tobytes() + np.asarray(direct).tobytes()).hexdigest()}


def start_together(spec: dict, processes: int, timeout_s: float = 300.0) -> list[dict]:
    """Run ``processes`` workers on ``spec`` released at the same moment; their results (index order).
    Raises RuntimeError with a worker's output when one fails."""
    barrier, out = Path(spec["barrier"]), Path(spec["out"])
    barrier.mkdir(parents=True, exist_ok=True)
    out.mkdir(parents=True, exist_ok=True)
    spec_path = out / "spec.json"
    spec_path.write_text(json.dumps(spec))
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    procs = [subprocess.Popen([sys.executable, "-m", "convsynth_jax.testing.cache_race", str(spec_path), str(i)],
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT, env=env) for i in range(processes)]
    try:
        deadline = time.monotonic() + timeout_s
        while len(list(barrier.glob("ready-*"))) < processes:
            if time.monotonic() > deadline or any(p.poll() is not None for p in procs):
                break
            time.sleep(0.01)
        (barrier / "go").touch()
        logs = [p.communicate(timeout=max(1.0, deadline - time.monotonic()))[0].decode(errors="replace") for p in procs]
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
                p.wait()
    failed = [(i, p.returncode, log) for i, (p, log) in enumerate(zip(procs, logs)) if p.returncode != 0]
    if failed:
        raise RuntimeError("\n".join(f"process {i} exited {rc}:\n{log[-3000:]}" for i, rc, log in failed))
    return [json.loads((out / f"result-{i}.json").read_text()) for i in range(processes)]


def main(argv: list[str]) -> None:
    spec = json.loads(Path(argv[0]).read_text())
    index = int(argv[1])
    result = _worker(spec, index)
    Path(spec["out"], f"result-{index}.json").write_text(json.dumps(result))


if __name__ == "__main__":
    main(sys.argv[1:])


def cache_report(cache: Path) -> dict:
    """Every entry of a cache folder read back: {kind: [entries, unreadable]} for the annotation pickles,
    the motion graphs and JAX's compilation cache, and ``leftover_temporaries``: hidden files other than
    locks (a temporary name left behind by a write that did not finish)."""
    import pickle

    from jax._src import compilation_cache

    from ..graph import load_graph

    report = {"annotations": [0, 0], "graphs": [0, 0], "jax_entries": [0, 0], "leftover_temporaries": 0}
    for p in (cache / "loo_cache").glob("annotations_*.pkl"):
        report["annotations"][0] += 1
        try:
            pickle.loads(p.read_bytes())
        except Exception:  # noqa: BLE001 - counted
            report["annotations"][1] += 1
    for p in (cache / "loo_cache").glob("graph_*.npz"):
        report["graphs"][0] += 1
        try:
            load_graph(p)
        except Exception:  # noqa: BLE001 - counted
            report["graphs"][1] += 1
    for p in (cache / "jax_cache").glob("*-cache"):
        report["jax_entries"][0] += 1
        try:
            compilation_cache.decompress_executable(p.read_bytes())
        except Exception:  # noqa: BLE001 - counted
            report["jax_entries"][1] += 1
    report["leftover_temporaries"] = sum(1 for p in cache.rglob(".*")
                                         if not p.name.endswith(".lock") and p.name != ".lockfile")
    return report
