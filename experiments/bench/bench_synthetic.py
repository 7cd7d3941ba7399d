"""Benchmark: generate the default synthetic corpus (17 sessions, 30 minutes, audio included).
Goal: under 60 s. Also times the same corpus without audio (the difference is the cost of
synthesizing and writing 2 x 30 minutes of 16 kHz speech), counts the planted events and measures
what makes the corpus hard (``data/synthetic/statistics.py``: realized co-occurrence rates vs the
configured Table 1 rates, with the generator's calibration report; words per pause-free stretch,
overlapping speech, coarticulated gestures, glitches).

Writes experiments/results/bench_synthetic.json.

    python experiments/bench/bench_synthetic.py [--no-audio-run-only]
"""
import argparse
import json
import tempfile
from pathlib import Path

import pandas as pd

from convsynth_jax.api import timed, write_result
from convsynth_jax.config import compose
from convsynth_jax.data import make_synthetic_corpus
from convsynth_jax.data.synthetic.statistics import difficulty, realized_rates


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--keep", help="write the corpus with audio here (kept) instead of a temporary folder")
    args = ap.parse_args()
    cfg = compose([])
    gen = cfg.corpus.generator
    with tempfile.TemporaryDirectory() as d:
        target = Path(args.keep) if args.keep else Path(d) / "c"
        root, secs = timed(make_synthetic_corpus, target, gen)
        size = sum(p.stat().st_size for p in root.iterdir()) / 1e6
        ev = pd.read_csv(root / "events.csv")
        rates = realized_rates(root)
        hard = difficulty(root)
        calibration = json.loads((root / "corpus.json").read_text()).get("calibration", {})
        _, secs_no_audio = timed(make_synthetic_corpus, Path(d) / "n", {**dict(gen), "write_audio": False})
    counts = ev.assign(source=ev["source"].fillna("")).groupby(["participant", "kind", "source"]).size()
    print(pd.DataFrame(rates).to_string(index=False))
    write_result("bench_synthetic", {"sessions": gen.num_sessions, "minutes": gen.num_sessions * gen.session_seconds / 60,
                              "seconds": secs, "seconds_without_audio": secs_no_audio,
                              "audio_seconds": secs - secs_no_audio, "megabytes": size, "goal_s": 60,
                              "events": {" ".join(k).strip(): int(v) for k, v in counts.items()},
                              "realized_rates": rates,
                              "max_abs_detector_minus_configured_pp": max(abs(r["detector_minus_configured_pp"])
                                                                          for r in rates),
                              "max_abs_window_minus_configured_pp": max(abs(r["window_minus_configured_pp"]) for r in rates),
                              "calibration": calibration, "difficulty": hard})
