"""Benchmark: speech timing of the synthetic corpus against real speech, both measured with the
annotation pipeline (``annotate.annotate_audio``; ``convsynth_jax.data.speech_timing``).

Real: every ``*.wav`` + ``*.TextGrid`` in ../shared/data/speech (two monologues of about 26 s, the
only real speech with word alignments we have). Synthetic: a generated corpus (default: the default
``corpus=synthetic``, written to a temporary folder; planting calibration off, which changes neither
the conversations nor the voices), or ``--corpus`` for an existing corpus folder. Prints and writes
a table of each distribution (n, median, IQR, 90th percentile) for both and the two-sample KS
distance, the filler rates, and the generation and annotation times.

Writes experiments/results/speech_timing.json and speech_timing.md (speech_timing_<config>.* for
another --corpus-config, e.g. synthetic_v4_timing, the timing before the calibration).

    python experiments/bench/speech_timing.py [--corpus-config synthetic] [--corpus DIR] [--sessions N]
"""
import argparse
import logging
import tempfile
from pathlib import Path


from omegaconf import OmegaConf

from convsynth_jax.config import compose
from convsynth_jax.data import make_synthetic_corpus
from convsynth_jax.data.speech_timing import DISTRIBUTIONS, compare, corpus_timing, speech_folder_timing
from convsynth_jax.io import load_corpus
from convsynth_jax.api import SHARED_DATA, timed, write_result, write_result_markdown


def _cell(s: dict) -> str:
    if not s.get("n"):
        return "-"
    return f"{s['median']:.2f} ({s['q25']:.2f}-{s['q75']:.2f}; {s['p90']:.2f}) n={s['n']}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--corpus-config", default="synthetic", help="conf/corpus entry to generate (default: synthetic)")
    ap.add_argument("--corpus", type=Path, help="measure this corpus folder instead of generating one")
    ap.add_argument("--sessions", type=int, help="measure only the first N sessions")
    ap.add_argument("--speech", type=Path, default=SHARED_DATA / "speech")
    args = ap.parse_args()
    logging.getLogger("convsynth_jax.annotate.audio").setLevel(logging.ERROR)  # octave-jump notes

    real, t_real = timed(speech_folder_timing, args.speech)
    gen_seconds = None
    with tempfile.TemporaryDirectory() as tmp:
        root = args.corpus
        if root is None:
            gen = OmegaConf.to_container(compose([f"corpus={args.corpus_config}"]).corpus.generator, resolve=True)
            gen["calibrate_rates"] = False
            root, gen_seconds = timed(make_synthetic_corpus, Path(tmp) / "c", gen)
        synthetic, t_syn = timed(corpus_timing, load_corpus(root), None, args.sessions)
    table = compare(real, synthetic)
    name = "speech_timing" if args.corpus is not None or args.corpus_config == "synthetic" else \
        f"speech_timing_{args.corpus_config}"
    overrides = [f"corpus={args.corpus_config}"] if args.corpus is None else None
    result = {"real": str(args.speech), "synthetic": str(args.corpus or f"corpus={args.corpus_config}"),
              "sessions": args.sessions, "distributions": table,
              "seconds": {"annotate_real": t_real, "generate_synthetic": gen_seconds, "annotate_synthetic": t_syn}}
    write_result(name, result, overrides=overrides)
    lines = ["| distribution | real: median (IQR; 90th) | synthetic: median (IQR; 90th) | KS |", "|---|---|---|---|"]
    for dist in DISTRIBUTIONS:
        row = table[dist]
        ks = "-" if row["ks"] != row["ks"] else f"{row['ks']:.3f}"
        lines.append(f"| {dist} | {_cell(row['real'])} | {_cell(row['synthetic'])} | {ks} |")
    f = table["fillers_per_100_words"]
    lines.append(f"| fillers per 100 words | {f['real']:.1f} | {f['synthetic']:.1f} | - |")
    write_result_markdown(name, lines, overrides=overrides)


if __name__ == "__main__":
    main()
