"""Benchmark: generate the default synthetic corpus (17 sessions, 30 minutes, audio included).
Goal: under 60 s. Also times the same corpus without audio (the difference is the cost of
synthesizing and writing 2 x 30 minutes of 16 kHz speech) and counts the planted events.
Writes experiments/results/bench_synthetic.json.

    python experiments/bench_synthetic.py
"""
import tempfile
from pathlib import Path

import pandas as pd
from _bench import timed, write

from convsynth_jax.config import compose
from convsynth_jax.data import make_synthetic_corpus

if __name__ == "__main__":
    cfg = compose([])
    gen = cfg.corpus.generator
    with tempfile.TemporaryDirectory() as d:
        root, secs = timed(make_synthetic_corpus, Path(d) / "c", gen)
        size = sum(p.stat().st_size for p in root.iterdir()) / 1e6
        ev = pd.read_csv(root / "events.csv")
        _, secs_no_audio = timed(make_synthetic_corpus, Path(d) / "n", {**dict(gen), "write_audio": False})
    counts = ev.assign(source=ev["source"].fillna("")).groupby(["participant", "kind", "source"]).size()
    write("bench_synthetic", {"sessions": gen.num_sessions, "minutes": gen.num_sessions * gen.session_seconds / 60,
                              "seconds": secs, "seconds_without_audio": secs_no_audio,
                              "audio_seconds": secs - secs_no_audio, "megabytes": size, "goal_s": 60,
                              "events": {" ".join(k).strip(): int(v) for k, v in counts.items()}})
