"""Benchmark: ``convsynth task=converse`` on 60 s of speech (docs/converse.md).

Input: character A speaks the real recordings of ``../shared/data/speech`` (their word TextGrids),
one after the other with 0.5 s pauses, repeated until 60 s (the last one cut, and its words after
the cut dropped); B is silent (a silent WAV and an empty transcript). Without ../shared, A speaks
session 0 of the synthetic corpus (its first 60 s) and B that session's other participant.
Models: the configured corpus's graphs (default: the synthetic corpus), fitted on every session.

Runs the task in fresh processes (``python -m convsynth_jax.config``) with the cache folder given
(default ``./data_cache``, where the corpus and its graphs are kept): a first run that may fit and
cache the models, then ``--repeats`` runs with everything cached. Figures: wall time of the whole
process and the task's own total, per part (inputs, corpus, models, synthesis, video), BVH frames
vs the audio's duration, windows, constraints met (checker, whole conversation), largest excess
acceleration at a cut. Acceptance: wall time <= 15 s on the cached runs (median), read as the task's
own total (``report.json`` timings; the process adds the package's start-up, about 5-9 s here for any
task) and as the whole process. ``--paper`` adds one run with the default ``search.matching=paper``.

    python experiments/bench/bench_converse.py [--repeats 2] [--cache data_cache] [--seconds 60] [--paper] \
        [search.matching=labels ...]
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _bench import REPO, SHARED, write

GOAL_S = 15.0


def speech_inputs(folder: Path, seconds: float) -> tuple[dict, str]:
    """(task overrides, description) of the input: shared speech for A and a silent B, or the synthetic corpus."""
    from convsynth_jax.io import load_audio, load_transcript, save_wav
    from convsynth_jax.io.transcripts import save_transcript_tsv

    speech = SHARED / "speech"
    if speech.is_dir():
        import pandas as pd

        recs = [(load_audio(w), load_transcript(w.with_suffix(".TextGrid"))) for w in sorted(speech.glob("*.wav"))]
        rate = recs[0][0].sample_rate
        gap = np.zeros(int(0.5 * rate), np.float32)
        parts, words, t = [], [], 0.0
        while t < seconds:
            for a, wd in recs:
                if t >= seconds:
                    break
                if a.sample_rate != rate:
                    raise SystemExit(f"{a.path}: sample rate {a.sample_rate}, expected {rate}")
                parts += [a.samples, gap]
                w = wd.copy()
                w[["start", "end"]] += t
                words.append(w)
                t += a.duration + 0.5
        samples = np.concatenate(parts)[:int(round(seconds * rate))]
        words = pd.concat(words, ignore_index=True)
        words = words[words["end"] <= seconds].reset_index(drop=True)
        save_wav(folder / "a.wav", samples, rate)
        save_transcript_tsv(words, folder / "a.tsv")
        save_wav(folder / "b.wav", np.zeros_like(samples), rate)
        (folder / "b.tsv").write_text("start\tend\tword\n")
        desc = f"A: {', '.join(w.name for w in sorted(speech.glob('*.wav')))} repeated to {seconds:g} s; B silent"
        return {"task.audio_a": folder / "a.wav", "task.transcript_a": folder / "a.tsv",
                "task.audio_b": folder / "b.wav", "task.transcript_b": folder / "b.tsv"}, desc
    from convsynth_jax.config import compose, to_params
    from convsynth_jax.tasks.common import open_corpus

    corpus = open_corpus(to_params(compose([])))
    s = corpus.sessions[0]
    out = {}
    for p, x in zip(s.participants, "ab"):
        a = p.load_audio()
        n = int(round(seconds * a.sample_rate))
        save_wav(folder / f"{x}.wav", a.samples[:n], a.sample_rate)
        w = p.load_transcript()
        save_transcript_tsv(w[w["end"] <= seconds].reset_index(drop=True), folder / f"{x}.tsv")
        out[f"task.audio_{x}"], out[f"task.transcript_{x}"] = folder / f"{x}.wav", folder / f"{x}.tsv"
    return out, f"synthetic corpus session {s.name}, first {seconds:g} s of both participants (../shared absent)"


def run(overrides: list, cache: Path, out: Path, check: bool = True) -> dict:
    env = dict(os.environ, CONVSYNTH_CACHE=str(cache), PYTHONPATH=str(REPO))
    cmd = [sys.executable, "-m", "convsynth_jax.config", "task=converse", *overrides, "progress=false",
           f"hydra.run.dir={out}"]
    load = os.getloadavg()[0]
    t = time.perf_counter()
    r = subprocess.run(cmd, env=env, capture_output=True, text=True, cwd=str(REPO))
    wall = time.perf_counter() - t
    if r.returncode != 0 and not check:
        return {"process_s": wall, "summary": json.loads((out / "summary.json").read_text()),
                "report_md": (out / "report.md").read_text() if (out / "report.md").is_file() else None}
    if r.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}")
    return {"process_s": wall, "summary": json.loads((out / "summary.json").read_text()),
            "report": json.loads((out / "report.json").read_text()), "load_avg_1min": [load, os.getloadavg()[0]]}


def figures(res: dict, out: Path, fps: float) -> dict:
    from convsynth_jax.io import load_bvh
    from convsynth_jax.render import probe_streams

    rep = res["report"]
    dur = rep["inputs"]["duration_s"]
    frames = {w: load_bvh(out / f"{w}.bvh").num_frames for w in "AB"}
    video = probe_streams(out / "conversation.mp4") if (out / "conversation.mp4").is_file() else None
    chars = rep["characters"]
    return {"process_s": res["process_s"], "task_total_s": rep["timings"]["total_s"], "parts_s": rep["timings"],
            "audio_s": dur, "bvh_frames": frames, "audio_frames": dur * fps,
            "frames_off_by": {w: abs(frames[w] - dur * fps) for w in "AB"},
            "windows": len(rep["plan"]["windows"]),
            "constraints_met": {w: f"{c['checker']['total']['met']}/{c['checker']['total']['total']}" for w, c in chars.items()},
            "excess_at_cuts_max": {w: max(c["continuity"]["at_cuts"].values(), default=0.0) for w, c in chars.items()},
            "excess_at_transitions_max": {w: c["continuity"]["at_synthetic_transitions_max"] for w, c in chars.items()},
            "search_s": {w: c["search_seconds"] for w, c in chars.items()},
            "report_written": (out / "report.md").is_file() and (out / "report.json").is_file(),
            "video": video, "load_avg_1min": res["load_avg_1min"]}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--cache", default=os.environ.get("CONVSYNTH_CACHE", str(REPO / "data_cache")))
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--paper", action="store_true", help="also one run with search.matching=paper (the default), "
                    "recorded whether it succeeds or not")
    ap.add_argument("overrides", nargs="*", help="further convsynth overrides (e.g. search.matching=labels, task.hop_s=15)")
    a = ap.parse_args()
    cache = Path(a.cache).resolve()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        inputs, desc = speech_inputs(tmp, a.seconds)
        ov = [f"{k}={v}" for k, v in inputs.items()] + list(a.overrides)
        first = run(ov, cache, tmp / "run0")
        fps = first["report"]["inputs"]["fps"]
        runs = []
        for i in range(a.repeats):
            r = run(ov, cache, tmp / f"run{i + 1}")
            runs.append(figures(r, tmp / f"run{i + 1}", fps))
        paper = None
        if a.paper:
            p = run([*ov, "search.matching=paper"], cache, tmp / "paper", check=False)
            paper = {"success": p["summary"].get("success"), "error": p["summary"].get("error"),
                     "report_md": p.get("report_md")}
    med = statistics.median(r["process_s"] for r in runs)
    result = {"input": desc, "seconds": a.seconds, "cache": str(cache), "overrides": a.overrides,
              "first_run": {"process_s": first["process_s"], "parts_s": first["report"]["timings"]},
              "cached_runs": runs, "process_s_median": med,
              "task_s_median": statistics.median(r["task_total_s"] for r in runs), "goal_s": GOAL_S,
              "goal_met_by_task_s": statistics.median(r["task_total_s"] for r in runs) <= GOAL_S,
              "goal_met_by_process_s": med <= GOAL_S, "paper_matching_run": paper}
    write("bench_converse", result, overrides=a.overrides)


if __name__ == "__main__":
    main()
