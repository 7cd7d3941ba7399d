"""Benchmark: generate the default synthetic corpus (17 sessions, 30 minutes, audio included).
Goal: under 60 s. Writes experiments/results/bench_synthetic.json.

    python experiments/bench_synthetic.py
"""
import tempfile
from pathlib import Path

from _bench import timed, write

from convsynth_jax.config import compose
from convsynth_jax.data import make_synthetic_corpus

if __name__ == "__main__":
    cfg = compose([])
    with tempfile.TemporaryDirectory() as d:
        root, secs = timed(make_synthetic_corpus, Path(d) / "c", cfg.corpus.generator)
        size = sum(p.stat().st_size for p in root.iterdir()) / 1e6
    write("bench_synthetic", {"sessions": cfg.corpus.generator.num_sessions,
                              "minutes": cfg.corpus.generator.num_sessions * cfg.corpus.generator.session_seconds / 60,
                              "seconds": secs, "megabytes": size, "goal_s": 60})
