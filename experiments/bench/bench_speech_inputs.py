"""Benchmark: word timings without a word-level transcript, and what they do to the phonemic clauses.

Real monologues: the two shared speech recordings (``shared/data/speech``, 26.7 s and 25.7 s) and the
BEAT2 take's speech (64.1 s), each with a word-level TextGrid (the reference). For each monologue the
words come from

- ``textgrid``: the word TextGrid (reference);
- ``none``: no transcript: the built-in offline recognizer (:func:`convsynth_jax.io.recognize.recognize_words`);
- ``srt``: sentence-level SubRip subtitles made by merging the reference words into phrases (a new phrase
  after a pause of 0.5 s or when it would pass 8 s, as subtitles are cut), read and aligned to the audio
  (:func:`convsynth_jax.io.recognize.align_phrases`), exactly as ``task=converse`` does with them;
- ``placeholder`` (control): the subtitles' spans filled with evenly spaced placeholder words ("word" at 3 words
  per second, the count rounded): speech where it is, but no real word timings.

Figures per monologue and word source: the recognizer's word error rate and the share of its correctly
recognized words (the matches of the edit-distance alignment) whose start lies within 50 ms of the
reference's; the same share for the aligned subtitles; seconds (wall and CPU) per 60 s of audio; and the
phonemic clauses (PC) the annotation (:func:`convsynth_jax.annotate.audio.annotate_audio`, default
parameters) finds: the share of the reference's PC clauses matched one-to-one by a clause with
intersection over union >= 0.5, the share of the source's PC boundaries (starts and ends) within 0.15 s of a
reference boundary, and the PC count relative to the reference's.

``--converse`` also runs ``task=converse`` (default settings, cached graphs) on each monologue with each
word source and on a stereo two-speaker case (the two speech recordings as channels 0 and 1, a
sentence-level two-tier TextGrid with one label broken over two lines, ``task.stereo`` +
``task.tier_a``/``task.tier_b``), and times 60 s of speech without a transcript (the BEAT2 take's first
60 s, ``--repeats`` runs, median).

    python experiments/bench/bench_speech_inputs.py [--converse] [--repeats 3] [--cache DIR]
"""
import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd
from _bench import REPO, SHARED, write, write_markdown

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

MONOLOGUES = {
    "acoustic_corpus": (SHARED / "speech" / "acoustic_corpus.wav", SHARED / "speech" / "acoustic_corpus.TextGrid"),
    "cold_corpus": (SHARED / "speech" / "cold_corpus.wav", SHARED / "speech" / "cold_corpus.TextGrid"),
    "beat2_scott": (SHARED / "beat2" / "wave16k" / "2_scott_0_1_1.wav",
                    SHARED / "beat2" / "textgrid" / "2_scott_0_1_1.TextGrid"),
}


# ----------------------------------------------------------------------------------------------- inputs
def phrases(words: pd.DataFrame, gap: float = 0.5, longest: float = 8.0) -> pd.DataFrame:
    """Sentence-level rows: consecutive words merged until a pause of ``gap`` s or ``longest`` s."""
    rows, cur = [], None
    for r in words.itertuples(index=False):
        if cur is not None and r.start - cur[1] < gap and r.end - cur[0] <= longest:
            cur = [cur[0], r.end, cur[2] + " " + r.word]
        else:
            if cur is not None:
                rows.append(cur)
            cur = [r.start, r.end, r.word]
    if cur is not None:
        rows.append(cur)
    return pd.DataFrame(rows, columns=["start", "end", "word"])


def write_srt(rows: pd.DataFrame, path: Path) -> Path:
    def stamp(t):
        ms = int(round(t * 1000))
        return f"{ms // 3600000:02d}:{ms // 60000 % 60:02d}:{ms // 1000 % 60:02d},{ms % 1000:03d}"
    blocks = [f"{i}\n{stamp(r.start)} --> {stamp(r.end)}\n{r.word}\n" for i, r in enumerate(rows.itertuples(), 1)]
    path.write_text("\n".join(blocks))
    return path


def placeholder_words(rows: pd.DataFrame, rate: float = 3.0) -> pd.DataFrame:
    """Each row's span filled with evenly spaced placeholder words at ``rate`` words per second."""
    out = []
    for r in rows.itertuples(index=False):
        n = max(1, int(round((r.end - r.start) * rate)))
        edges = np.linspace(r.start, r.end, n + 1)
        out += [(float(a), float(b), "word") for a, b in zip(edges[:-1], edges[1:])]
    return pd.DataFrame(out, columns=["start", "end", "word"])


# ----------------------------------------------------------------------------------------------- measures
def _norm(w: str) -> str:
    import re

    return re.sub(r"[^a-z0-9']", "", str(w).lower().replace("\u2019", "'")).strip("'")


def word_alignment(ref: list, hyp: list):
    """(edits, matched index pairs) of the Levenshtein alignment of two word lists."""
    n, m = len(ref), len(hyp)
    d = np.zeros((n + 1, m + 1), np.int64)
    d[:, 0], d[0, :] = np.arange(n + 1), np.arange(m + 1)
    for i in range(1, n + 1):
        for j in range(1, m + 1):
            d[i, j] = min(d[i - 1, j] + 1, d[i, j - 1] + 1, d[i - 1, j - 1] + (ref[i - 1] != hyp[j - 1]))
    pairs, i, j = [], n, m
    while i > 0 and j > 0:
        if d[i, j] == d[i - 1, j - 1] + (ref[i - 1] != hyp[j - 1]):
            if ref[i - 1] == hyp[j - 1]:
                pairs.append((i - 1, j - 1))
            i, j = i - 1, j - 1
        elif d[i, j] == d[i - 1, j] + 1:
            i -= 1
        else:
            j -= 1
    return int(d[n, m]), pairs[::-1]


def word_figures(ref: pd.DataFrame, hyp: pd.DataFrame) -> dict:
    r = [_norm(w) for w in ref["word"]]
    h = [_norm(w) for w in hyp["word"]]
    edits, pairs = word_alignment(r, h)
    err = np.array([abs(hyp["start"].iat[j] - ref["start"].iat[i]) for i, j in pairs])
    return {"ref_words": len(r), "words": len(h), "wer": edits / max(1, len(r)), "correct": len(pairs),
            "starts_within_50ms": float(np.mean(err < 0.05)) if len(err) else 0.0,
            "start_error_median_s": float(np.median(err)) if len(err) else None}


def pc_clauses(seg: pd.DataFrame) -> np.ndarray:
    pc = seg[seg["kind"] == "PC"]
    return pc[["start", "end"]].to_numpy(float)


def clause_figures(ref: np.ndarray, got: np.ndarray, iou_min: float = 0.5, tol: float = 0.15) -> dict:
    from scipy.optimize import linear_sum_assignment

    matched = 0
    if len(ref) and len(got):
        inter = np.clip(np.minimum(ref[:, None, 1], got[None, :, 1]) - np.maximum(ref[:, None, 0], got[None, :, 0]), 0,
                        None)
        union = (ref[:, None, 1] - ref[:, None, 0]) + (got[None, :, 1] - got[None, :, 0]) - inter
        iou = np.where(union > 0, inter / np.maximum(union, 1e-9), 0.0)
        rows, cols = linear_sum_assignment(-iou)
        matched = int(np.sum(iou[rows, cols] >= iou_min))
    rb = ref.reshape(-1)
    gb = got.reshape(-1)
    near = float(np.mean([np.min(np.abs(rb - b)) <= tol for b in gb])) if len(gb) and len(rb) else 0.0
    return {"pc_ref": len(ref), "pc": len(got), "matched_iou50": matched / max(1, len(ref)),
            "boundaries_within_015": near, "count_ratio": len(got) / max(1, len(ref))}


# ----------------------------------------------------------------------------------------------- parts
def annotation_part(params) -> dict:
    from convsynth_jax.annotate.audio import annotate_audio
    from convsynth_jax.io import load_audio, load_transcript
    from convsynth_jax.io.recognize import align_phrases, recognize_words

    out = {}
    tmp = Path(tempfile.mkdtemp(prefix="speech_inputs_"))
    recognize_words(np.zeros(1600, np.float32), 16000)        # load the models once (cached by the library)
    for name, (wav, tg) in MONOLOGUES.items():
        a = load_audio(wav)
        a = a.channel(0) if a.num_channels > 1 else a
        ref = load_transcript(tg)
        rows = phrases(ref)
        srt = load_transcript(write_srt(rows, tmp / f"{name}.srt"))
        entry = {"audio_s": a.duration, "srt_rows": len(srt)}
        t, c = time.perf_counter(), time.process_time()
        rec = recognize_words(a.samples, a.sample_rate)
        entry["recognize"] = {**word_figures(ref, rec), "wall_per_60s": (time.perf_counter() - t) * 60 / a.duration,
                              "cpu_per_60s": (time.process_time() - c) * 60 / a.duration}
        t, c = time.perf_counter(), time.process_time()
        ali = align_phrases(srt, a.samples, a.sample_rate, str(tmp / f"{name}.srt"))
        entry["align_srt"] = {**word_figures(ref, ali), "wall_per_60s": (time.perf_counter() - t) * 60 / a.duration,
                              "cpu_per_60s": (time.process_time() - c) * 60 / a.duration}
        sources = {"textgrid": ref, "none": rec, "srt": ali, "placeholder": placeholder_words(rows)}
        seg = {k: annotate_audio(w, a, params.annotate) for k, w in sources.items()}
        refpc = pc_clauses(seg["textgrid"])
        entry["clauses"] = {k: clause_figures(refpc, pc_clauses(s)) for k, s in seg.items()}
        for k, w in sources.items():
            w.to_csv(tmp / f"{name}_{k}.tsv", sep="\t", index=False)
        out[name] = entry
        print(name, json.dumps(entry, default=float), flush=True)
    return out


def stereo_case(folder: Path) -> dict:
    """The two speech recordings as one stereo WAV (A = channel 0, B = channel 1) and a sentence-level
    two-tier TextGrid (tiers 'A' and 'B'), one of whose labels runs over two lines."""
    from convsynth_jax.io import load_audio, load_transcript, save_wav

    (wa, ta), (wb, tb) = MONOLOGUES["acoustic_corpus"], MONOLOGUES["cold_corpus"]
    a, b = load_audio(wa), load_audio(wb)
    n = max(a.num_samples, b.num_samples)
    x = np.zeros((n, 2), np.float32)
    x[:a.num_samples, 0], x[:b.num_samples, 1] = a.samples, b.samples
    save_wav(folder / "two_speakers.wav", x, a.sample_rate)
    dur = n / a.sample_rate
    tiers = {"A": phrases(load_transcript(ta)), "B": phrases(load_transcript(tb))}
    # one label broken over lines (as Praat writes a label holding a line break)
    w = tiers["A"]["word"].iat[1].split()
    tiers["A"].loc[1, "word"] = " ".join(w[:len(w) // 2]) + "\n" + " ".join(w[len(w) // 2:])
    lines = ['File type = "ooTextFile"', 'Object class = "TextGrid"', "", "xmin = 0", f"xmax = {dur}",
             "tiers? <exists>", f"size = {len(tiers)}", "item []:"]
    for k, (name, rows) in enumerate(tiers.items(), 1):
        iv, t = [], 0.0
        for r in rows.itertuples(index=False):
            if r.start > t:
                iv.append((t, r.start, ""))
            iv.append((r.start, r.end, r.word))
            t = r.end
        iv.append((t, dur, ""))
        lines += [f"    item [{k}]:", '        class = "IntervalTier"', f'        name = "{name}"', "        xmin = 0",
                  f"        xmax = {dur}", f"        intervals: size = {len(iv)}"]
        for i, (s, e, text) in enumerate(iv, 1):
            lines += [f"        intervals [{i}]:", f"            xmin = {s}", f"            xmax = {e}",
                      f'            text = "{text}"']
    (folder / "two_speakers.TextGrid").write_text("\n".join(lines) + "\n")
    speech = {k: float((r["end"] - r["start"]).sum()) for k, r in tiers.items()}
    return {"wav": folder / "two_speakers.wav", "textgrid": folder / "two_speakers.TextGrid", "speech_s": speech}


def converse_part(cache: Path, repeats: int) -> dict:
    from bench_converse import run

    out = {}
    tmp = Path(tempfile.mkdtemp(prefix="speech_converse_"))

    def clauses(res, who="A"):
        segs = res["report"]["segments"][who]
        return np.array([[s["start"], s["end"]] for s in segs if s["kind"] == "PC"], float).reshape(-1, 2)

    def met(res):
        sp = res["summary"]["speakers"]
        return {w: f"{sp[w]['constraints']['met']}/{sp[w]['constraints']['total']}" for w in "AB"}, \
            sum(sp[w]["constraints"]["met"] for w in "AB"), sum(sp[w]["constraints"]["total"] for w in "AB")

    totals = [0, 0]
    for name, (wav, tg) in MONOLOGUES.items():
        from convsynth_jax.io import load_transcript

        srt = write_srt(phrases(load_transcript(tg)), tmp / f"{name}.srt")
        runs = {}
        for src, over in (("textgrid", [f"task.transcript_a={tg}"]), ("none", []), ("srt", [f"task.transcript_a={srt}"])):
            res = run([f"task.audio_a={wav}", *over, "task.video=false"], cache, tmp / f"{name}_{src}")
            m, k, n = met(res)
            totals[0] += k
            totals[1] += n
            runs[src] = {"met": m, "task_s": res["summary"]["task_seconds"], "process_s": res["process_s"],
                         "process_cpu_s": res["process_cpu_s"], "pc": clauses(res)}
        ref = runs["textgrid"]["pc"]
        for src in runs:
            runs[src]["clauses"] = clause_figures(ref, runs[src].pop("pc"))
        out[name] = runs
        print(name, json.dumps(runs, default=float), flush=True)
    out["constraints_met_share"] = totals[0] / max(1, totals[1])
    st = stereo_case(tmp)
    res = run([f"task.stereo={st['wav']}", f"task.transcript_a={st['textgrid']}", f"task.transcript_b={st['textgrid']}",
               "task.tier_a=A", "task.tier_b=B", "task.video=false"], cache, tmp / "stereo")
    out["stereo_two_tier"] = {"met": met(res)[0], "speech_s": st["speech_s"],
                              "pc": {w: len(clauses(res, w)) for w in "AB"},
                              "pc_per_4s": {w: len(clauses(res, w)) / (st["speech_s"][w] / 4.0) for w in "AB"},
                              "task_s": res["summary"]["task_seconds"]}
    print("stereo", json.dumps(out["stereo_two_tier"], default=float), flush=True)
    # 60 s of speech without a transcript: the whole task, models cached
    from convsynth_jax.io import load_audio, save_wav

    a = load_audio(MONOLOGUES["beat2_scott"][0])
    save_wav(tmp / "beat2_60s.wav", a.samples[:60 * a.sample_rate], a.sample_rate)
    times = []
    for i in range(repeats):
        res = run([f"task.audio_a={tmp / 'beat2_60s.wav'}", "task.video=false"], cache, tmp / f"t60_{i}")
        times.append({"task_s": res["summary"]["task_seconds"], "process_s": res["process_s"],
                      "process_cpu_s": res["process_cpu_s"], "inputs_s": res["summary"]["timings"]["inputs_s"],
                      "load": res["load_avg_1min"]})
    out["no_transcript_60s"] = {"runs": times, "median_task_s": statistics.median(t["task_s"] for t in times),
                                "median_process_s": statistics.median(t["process_s"] for t in times),
                                "median_process_cpu_s": statistics.median(t["process_cpu_s"] for t in times)}
    print("60s", json.dumps(out["no_transcript_60s"], default=float), flush=True)
    return out


def markdown(ann: dict, conv: dict | None) -> list:
    lines = ["| monologue | s | recognizer WER | starts within 50 ms (recognized / aligned SRT) | recognizer s per 60 s "
             "(wall / CPU) | alignment s per 60 s (wall / CPU) |", "|---|---|---|---|---|---|"]
    for name, e in ann.items():
        r, s = e["recognize"], e["align_srt"]
        lines.append(f"| {name} | {e['audio_s']:.1f} | {r['wer']:.2f} ({r['correct']}/{r['ref_words']} correct) | "
                     f"{r['starts_within_50ms']:.2f} / {s['starts_within_50ms']:.2f} | {r['wall_per_60s']:.1f} / "
                     f"{r['cpu_per_60s']:.1f} | {s['wall_per_60s']:.1f} / {s['cpu_per_60s']:.1f} |")
    lines += ["", "| monologue | words from | PC (reference) | matched IoU >= 0.5 | boundaries within 0.15 s | "
              "count ratio |", "|---|---|---|---|---|---|"]
    for name, e in ann.items():
        for k, c in e["clauses"].items():
            lines.append(f"| {name} | {k} | {c['pc']} ({c['pc_ref']}) | {c['matched_iou50']:.2f} | "
                         f"{c['boundaries_within_015']:.2f} | {c['count_ratio']:.2f} |")
    if conv:
        lines += ["", "| monologue | words from | constraints met A, B | PC matched IoU >= 0.5 | boundaries within "
                  "0.15 s | count ratio | task s |", "|---|---|---|---|---|---|---|"]
        for name in MONOLOGUES:
            for k, r in conv[name].items():
                c = r["clauses"]
                lines.append(f"| {name} | {k} | {r['met']['A']}, {r['met']['B']} | {c['matched_iou50']:.2f} | "
                             f"{c['boundaries_within_015']:.2f} | {c['count_ratio']:.2f} | {r['task_s']:.1f} |")
        st = conv["stereo_two_tier"]
        lines += ["", f"Constraints met over the nine monologue runs: {conv['constraints_met_share']:.3f}.", "",
                  f"Stereo two-tier TextGrid: PC clauses A {st['pc']['A']} in {st['speech_s']['A']:.1f} s of "
                  f"transcribed speech ({st['pc_per_4s']['A']:.2f} per 4 s), B {st['pc']['B']} in "
                  f"{st['speech_s']['B']:.1f} s ({st['pc_per_4s']['B']:.2f} per 4 s); constraints met "
                  f"{st['met']['A']}, {st['met']['B']}.", "",
                  f"60 s without a transcript: task median {conv['no_transcript_60s']['median_task_s']:.1f} s, "
                  f"process median {conv['no_transcript_60s']['median_process_s']:.1f} s "
                  f"(CPU {conv['no_transcript_60s']['median_process_cpu_s']:.1f} s)."]
    return lines


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--converse", action="store_true")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--cache", default=os.environ.get("CONVSYNTH_CACHE", str(REPO / "data_cache")))
    ap.add_argument("--name", default="bench_speech_inputs")
    a = ap.parse_args()
    from convsynth_jax.config import default_params

    params = default_params([f"cache_dir={a.cache}"])
    ann = annotation_part(params)
    conv = converse_part(Path(a.cache).resolve(), a.repeats) if a.converse else None
    result = {"annotation": ann, "converse": conv, "load_avg": os.getloadavg()}
    write(a.name, result)
    write_markdown(a.name, markdown(ann, conv))


if __name__ == "__main__":
    main()
