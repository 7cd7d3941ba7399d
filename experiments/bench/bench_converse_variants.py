"""Benchmark: ``convsynth task=converse`` with default settings on real speech as new users bring it.

The shared recordings (``../shared/data/speech``, the BEAT2 take's speech) are what the project was built
and measured on. A user's speech differs in speaker, tempo, pitch, file format, transcript format and turn
taking. This script turns the real recordings into inputs that differ in those ways, runs the task on each
with default settings in a fresh process, and reports the same figures as ``bench_converse.py``: success,
BVH as long as the audio, constraints met by kind (the independent checker over the whole conversation),
windows, transitions per minute, task seconds per minute of speech, peak memory of the process.

Inputs (all built here; each real recording keeps its own words, shifted and scaled with its audio):
- ``slow_low_flac``: acoustic_corpus 0.8x slower and 4 semitones lower (librosa), 44.1 kHz FLAC, words in
  a long-format TextGrid; only A given (B silent).
- ``fast_high_whisper``: cold_corpus 1.2x faster and 3 semitones higher, 22.05 kHz 24-bit WAV, words as
  Whisper JSON; only A given.
- ``backchannels_stereo48k``: one 48 kHz stereo WAV: A speaks the BEAT2 take; B answers with "okay" (cut
  from the take, pitch-shifted per occurrence) every 6-9 s and "so" once; CSV transcripts.
- ``overlap_ogg_mp3``: A (OGG) speaks cold_corpus; B (MP3) starts the BEAT2 take at 15 s, talking over
  A's last 10 s; IBM-style TSV transcripts.
- ``turns_6min``: six minutes of alternating turns (A and B each speak the three recordings, slowed or
  sped up by turn, 0.4-1.2 s between turns): chained windows with both characters speaking.

    python experiments/bench/bench_converse_variants.py [--cache data_cache] [--only NAME ...] [overrides ...]
"""
import argparse
import json
import os
import resource
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd
from _bench import REPO, SHARED, write

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from bench_converse import input_figures, run, summed_by_kind  # noqa: E402


def _load(name: str):
    from convsynth_jax.io import load_audio, load_transcript

    if name == "beat2":
        w = SHARED / "beat2" / "wave16k" / "2_scott_0_1_1.wav"
        g = SHARED / "beat2" / "textgrid" / "2_scott_0_1_1.TextGrid"
    else:
        w, g = SHARED / "speech" / f"{name}.wav", SHARED / "speech" / f"{name}.TextGrid"
    a = load_audio(w)
    x = np.asarray(a.samples, np.float32)
    return (x[:, 0] if x.ndim == 2 else x), a.sample_rate, load_transcript(g)


def _transform(x, rate, words, speed=1.0, semitones=0.0, out_rate=None):
    """Tempo (time-stretch, pitch kept), pitch shift and resampling; the words' times scale with the tempo."""
    import librosa

    y = x
    if speed != 1.0:
        y = librosa.effects.time_stretch(y, rate=speed)
    if semitones:
        y = librosa.effects.pitch_shift(y, sr=rate, n_steps=semitones)
    if out_rate and out_rate != rate:
        y = librosa.resample(y, orig_sr=rate, target_sr=out_rate)
        rate = out_rate
    w = words.copy()
    w[["start", "end"]] = w[["start", "end"]] / speed
    return np.clip(y, -1, 1).astype(np.float32), rate, w


def _whisper_json(words: pd.DataFrame, path: Path) -> None:
    segs, cur = [], []
    for r in words.itertuples(index=False):
        if cur and r.start - cur[-1]["end"] > 0.5:
            segs.append(cur)
            cur = []
        cur.append({"word": " " + r.word, "start": round(r.start, 3), "end": round(r.end, 3), "probability": 0.9})
    if cur:
        segs.append(cur)
    path.write_text(json.dumps({"segments": [{"id": i, "start": s[0]["start"], "end": s[-1]["end"],
                                              "text": "".join(w["word"] for w in s), "words": s}
                                             for i, s in enumerate(segs)]}))


def _place(n, parts):
    """One track of n samples from (samples, words, at seconds, rate) parts, and their words."""
    buf, ws = np.zeros(n, np.float32), []
    for x, w, at, rate in parts:
        k = int(round(at * rate))
        m = max(0, min(n - k, len(x)))
        buf[k:k + m] += x[:m]
        ws.append(w.assign(start=w["start"] + at, end=w["end"] + at))
    words = pd.concat(ws).sort_values("start").reset_index(drop=True) if ws else pd.DataFrame(columns=["start", "end", "word"])
    dur = n / parts[0][3] if parts else 0.0
    return np.clip(buf, -1, 1), words[words["end"] <= dur].reset_index(drop=True)


def _cut(x, rate, words, word_index):
    r = words.iloc[word_index]
    a, b = max(0.0, r.start - 0.05), r.end + 0.05
    seg = x[int(a * rate):int(b * rate)]
    return seg, pd.DataFrame({"start": [r.start - a], "end": [r.end - a], "word": [r.word]})


def build(folder: Path) -> dict:
    """name -> (task overrides, description)."""
    import soundfile

    from convsynth_jax.io import save_wav
    from convsynth_jax.io.transcripts import save_textgrid, save_transcript_tsv

    out = {}
    ac, cold, beat = _load("acoustic_corpus"), _load("cold_corpus"), _load("beat2")

    d = folder / "slow_low_flac"
    d.mkdir()
    x, r, w = _transform(*ac, speed=0.8, semitones=-4, out_rate=44100)
    soundfile.write(d / "a.flac", x, r, subtype="PCM_16")
    save_textgrid(w, d / "a.TextGrid", len(x) / r)
    out["slow_low_flac"] = ({"task.audio_a": d / "a.flac", "task.transcript_a": d / "a.TextGrid"},
                            "acoustic_corpus 0.8x, -4 st, 44.1 kHz FLAC, long TextGrid; B not given")

    d = folder / "fast_high_whisper"
    d.mkdir()
    x, r, w = _transform(*cold, speed=1.2, semitones=3, out_rate=22050)
    soundfile.write(d / "a.wav", x, r, subtype="PCM_24")
    _whisper_json(w, d / "a.json")
    out["fast_high_whisper"] = ({"task.audio_a": d / "a.wav", "task.transcript_a": d / "a.json"},
                                "cold_corpus 1.2x, +3 st, 22.05 kHz 24-bit WAV, Whisper JSON; B not given")

    d = folder / "backchannels_stereo48k"
    d.mkdir()
    bx, br, bw = _transform(*beat, out_rate=48000)
    n = len(bx)
    okay = int(np.flatnonzero(bw["word"].str.lower() == "okay")[0])
    so = int(np.flatnonzero(bw["word"].str.lower() == "so")[0])
    parts, t, rng = [], 4.0, np.random.default_rng(0)
    while t < n / br - 2:
        seg, sw = _cut(bx, br, bw, okay)
        y, _, _ = _transform(seg, br, sw, semitones=float(rng.uniform(-3, 3)))
        parts.append((y, sw, t, br))
        t += float(rng.uniform(6, 9))
    seg, sw = _cut(bx, br, bw, so)
    parts.append((seg, sw, 30.3, br))
    bb, bwords = _place(n, parts)
    soundfile.write(d / "ab.wav", np.stack([bx, bb], 1), br, subtype="PCM_16")
    bw.to_csv(d / "a.csv", index=False)
    bwords.to_csv(d / "b.csv", index=False)
    out["backchannels_stereo48k"] = ({"task.stereo": d / "ab.wav", "task.transcript_a": d / "a.csv",
                                      "task.transcript_b": d / "b.csv"},
                                     f"48 kHz stereo; A the BEAT2 take, B {len(parts)} back-channels; CSV words")

    d = folder / "overlap_ogg_mp3"
    d.mkdir()
    r = 16000
    n = int((15.0 + len(beat[0]) / beat[1]) * r)
    xa, wa = _place(n, [(cold[0], cold[2], 0.0, r)])
    xb, wb = _place(n, [(beat[0], beat[2], 15.0, r)])
    soundfile.write(d / "a.ogg", xa, r, format="OGG", subtype="VORBIS")
    soundfile.write(d / "b.mp3", xb, r, format="MP3")
    save_transcript_tsv(wa, d / "a.tsv")
    save_transcript_tsv(wb, d / "b.tsv")
    out["overlap_ogg_mp3"] = ({"task.audio_a": d / "a.ogg", "task.transcript_a": d / "a.tsv",
                               "task.audio_b": d / "b.mp3", "task.transcript_b": d / "b.tsv"},
                              "A cold_corpus (OGG), B the BEAT2 take from 15 s (MP3), 10 s of overlap")

    d = folder / "turns_6min"
    d.mkdir()
    r, total = 16000, 360.0
    n = int(total * r)
    recs = [ac, cold, beat]
    pa, pb, t, k = [], [], 0.0, 0
    rng = np.random.default_rng(1)
    while t < total - 5:
        speed = float(rng.choice([0.9, 1.0, 1.1]))
        x, _, w = _transform(*recs[k % 3], speed=speed)
        (pa if k % 2 == 0 else pb).append((x, w, t, r))
        t += len(x) / r + float(rng.uniform(0.4, 1.2))
        k += 1
    xa, wa = _place(n, pa)
    xb, wb = _place(n, pb)
    save_wav(d / "a.wav", xa, r)
    save_wav(d / "b.wav", xb, r)
    save_transcript_tsv(wa, d / "a.tsv")
    save_transcript_tsv(wb, d / "b.tsv")
    out["turns_6min"] = ({"task.audio_a": d / "a.wav", "task.transcript_a": d / "a.tsv",
                          "task.audio_b": d / "b.wav", "task.transcript_b": d / "b.tsv"},
                         f"{total:g} s of {k} alternating turns of the three recordings at 0.9-1.1x")
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cache", default=os.environ.get("CONVSYNTH_CACHE", str(REPO / "data_cache")))
    ap.add_argument("--only", nargs="*", default=None)
    ap.add_argument("--name", default="bench_converse_variants")
    ap.add_argument("overrides", nargs="*")
    a = ap.parse_args()
    if not (SHARED / "speech").is_dir() or not (SHARED / "beat2").is_dir():
        raise SystemExit(f"needs the shared recordings in {SHARED}")
    cache = Path(a.cache).resolve()
    per = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for name, (ov, desc) in build(tmp).items():
            if a.only and name not in a.only:
                continue
            o = tmp / f"out_{name}"
            r = run([*(f"{k}={v}" for k, v in ov.items()), *a.overrides], cache, o, check=False)
            peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
            if "report" not in r:
                per[name] = {"description": desc, "success": False, "error": r["summary"].get("error"),
                             "process_s": r["process_s"]}
            else:
                per[name] = {"description": desc, **input_figures(r, o),
                             "peak_rss_mb_at_most": peak / 1024.0,   # the largest of this and earlier runs
                             "load_avg_1min": r["load_avg_1min"]}
            print(name, json.dumps({k: per[name].get(k) for k in ("success", "met_by_kind", "error")}), flush=True)
    kinds, met, total = summed_by_kind(per)
    pc = kinds.get("PC", [0, 0])
    ok = all(f.get("success") and f.get("frames_as_long_as_audio") for f in per.values())
    write(a.name, {"cache": str(cache), "overrides": a.overrides, "inputs": per,
                   "summed": {"by_kind": {k: {"met": m, "total": t} for k, (m, t) in kinds.items()},
                              "met_share": met / total if total else None,
                              "pc_share": pc[0] / pc[1] if pc[1] else None, "all_succeed": ok,
                              "acceptance_met": ok and total > 0 and met >= 0.9 * total and pc[0] >= 0.85 * pc[1]}},
          overrides=a.overrides)


if __name__ == "__main__":
    main()
