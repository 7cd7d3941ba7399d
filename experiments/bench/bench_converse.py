"""Benchmark: ``convsynth task=converse`` with default settings on real speech (docs/converse.md).

Inputs (built by the script from ``../shared/data``; each is one conversation):
- each shared recording as A with a silent B: ``speech/acoustic_corpus``, ``speech/cold_corpus`` and the
  BEAT2 take's speech (``beat2/wave16k`` + ``beat2/textgrid``, 32-bit float WAV, long-format TextGrid);
- ``exchange``: A speaks ``acoustic_corpus``, then B answers with ``cold_corpus`` after a 0.6 s gap (each
  silent while the other speaks);
- ``timing``: A speaks the shared recordings one after the other with 0.5 s pauses until ``--seconds``
  (default 60), B silent: the speed figure (run ``--repeats`` more times with everything cached).
Without ../shared, A speaks session 0 of the synthetic corpus (its first 60 s) and B that session's other
participant (the timing input only).
Models: the configured corpus's graphs (default: the synthetic corpus), fitted on every session.

Runs the task in fresh processes (``python -m convsynth_jax.config``) with the cache folder given (default
``./data_cache``). Figures per input: success, BVH frames vs the audio, windows, constraints met by kind
(the checker over the whole conversation), the excess acceleration at cuts beside the largest at synthetic
transitions (seams), synthetic transitions per minute, seconds of task per minute of speech. Acceptance
(summed over the inputs): every input succeeds with BVH as long as the audio, at least 90% of all
constraints and 85% of PC constraints met; the timing input in at most 15 s once the models are cached,
video included, read as the task's own total (``report.json`` timings; the process adds the package's
start-up) and as the whole process.

    python experiments/bench/bench_converse.py [--repeats 2] [--cache data_cache] [--seconds 60] [overrides ...]
"""
import argparse
import json
import os
import statistics
import tempfile
from pathlib import Path

from convsynth_jax.api import REPO, SHARED_DATA, run_convsynth, write_result
from convsynth_jax.data.conversation_inputs import exchange, repeated_speech, silent_partner

GOAL_S = 15.0


def task_files(files) -> dict:
    """The task's overrides (``task.audio_a`` ...) naming a conversation's files."""
    return {f"task.{k}": v for k, v in files._asdict().items()}


def speech_inputs(folder: Path, seconds: float) -> tuple[dict, str]:
    """(task overrides, description) of the input: shared speech for A and a silent B, or the synthetic corpus."""
    from convsynth_jax.io import save_wav
    from convsynth_jax.io.transcripts import save_transcript_tsv

    speech = SHARED_DATA / "speech"
    if speech.is_dir():
        wavs = sorted(speech.glob("*.wav"))
        files, _ = repeated_speech(folder, [(w, w.with_suffix(".TextGrid")) for w in wavs], seconds)
        return task_files(files), f"A: {', '.join(w.name for w in wavs)} repeated to {seconds:g} s; B silent"
    from convsynth_jax.config import compose, to_params
    from convsynth_jax.api import open_corpus

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
    r = run_convsynth(["task=converse", *overrides, "progress=false"], out, cache)
    if r.returncode != 0 and not check:
        summ = out / "summary.json"
        return {"process_s": r.wall_s, "process_cpu_s": r.cpu_s,
                "summary": json.loads(summ.read_text()) if summ.is_file() else {"error": r.stderr[-2000:]},
                "report_md": (out / "report.md").read_text() if (out / "report.md").is_file() else None}
    r.check()
    return {"process_s": r.wall_s, "process_cpu_s": r.cpu_s, "summary": json.loads((out / "summary.json").read_text()),
            "report": json.loads((out / "report.json").read_text()), "load_avg_1min": r.load_avg_1min}


def figures(res: dict, out: Path, fps: float) -> dict:
    from convsynth_jax.io import load_bvh
    from convsynth_jax.render import probe_streams

    rep = res["report"]
    dur = rep["inputs"]["duration_s"]
    frames = {w: load_bvh(out / f"{w}.bvh").num_frames for w in "AB"}
    video = probe_streams(out / "conversation.mp4") if (out / "conversation.mp4").is_file() else None
    chars = rep["characters"]
    return {"process_s": res["process_s"], "process_cpu_s": res["process_cpu_s"],
            "task_total_s": rep["timings"]["total_s"], "parts_s": rep["timings"],
            "audio_s": dur, "bvh_frames": frames, "audio_frames": dur * fps,
            "frames_off_by": {w: abs(frames[w] - dur * fps) for w in "AB"},
            "windows": len(rep["plan"]["windows"]),
            "constraints_met": {w: f"{c['checker']['total']['met']}/{c['checker']['total']['total']}" for w, c in chars.items()},
            "excess_at_cuts_max": {w: max(c["continuity"]["at_cuts"].values(), default=0.0) for w, c in chars.items()},
            "excess_at_transitions_max": {w: c["continuity"]["at_synthetic_transitions_max"] for w, c in chars.items()},
            "search_s": {w: c["search_seconds"] for w, c in chars.items()},
            "report_written": (out / "report.md").is_file() and (out / "report.json").is_file(),
            "video": video, "load_avg_1min": res["load_avg_1min"]}


def real_inputs(folder: Path) -> dict:
    """name -> task overrides of the benchmark's real inputs (empty without ../shared)."""
    out = {}
    sp = SHARED_DATA / "speech"
    for w in sorted(sp.glob("*.wav")) if sp.is_dir() else []:
        out[w.stem] = task_files(silent_partner(folder / w.stem, w, w.with_suffix(".TextGrid"))[0])
    beat = SHARED_DATA / "beat2"
    for w in sorted((beat / "wave16k").glob("*.wav")) if beat.is_dir() else []:
        grid = beat / "textgrid" / f"{w.stem}.TextGrid"
        if grid.is_file():
            out[f"beat2_{w.stem}"] = task_files(silent_partner(folder / f"beat2_{w.stem}", w, grid)[0])
    if sp.is_dir():
        pair = [(sp / f"{n}.wav", sp / f"{n}.TextGrid") for n in ("acoustic_corpus", "cold_corpus")]
        out["exchange"] = task_files(exchange(folder / "exchange", *pair, gap=0.6)[0])
    return out


def input_figures(res: dict, out: Path) -> dict:
    """The per-input figures of the issue: success, lengths, constraints met by kind, seams, transitions."""
    from convsynth_jax.io import load_bvh

    rep = res["report"]
    fps = rep["inputs"]["fps"]
    dur = rep["inputs"]["duration_s"]
    chars = rep["characters"]
    frames = {w: load_bvh(out / f"{w}.bvh").num_frames for w in "AB"}
    kinds = {}
    for c in chars.values():
        for k, v in c["checker"]["total"]["by_kind"].items():
            kinds.setdefault(k, [0, 0])
            kinds[k][0] += v["met"]
            kinds[k][1] += v["total"]
    return {"success": bool(rep["success"]), "audio_s": dur, "bvh_frames": frames,
            "frames_as_long_as_audio": all(abs(f - dur * fps) <= 1.0 for f in frames.values()),
            "windows": len(rep["plan"]["windows"]),
            "met_by_kind": {k: {"met": m, "total": t} for k, (m, t) in kinds.items()},
            "met_by_character": {w: f"{c['checker']['total']['met']}/{c['checker']['total']['total']}"
                                 for w, c in chars.items()},
            "excess_at_cuts_max": {w: max(c["continuity"]["at_cuts"].values(), default=None) for w, c in chars.items()},
            "excess_at_transitions_max": {w: c["continuity"]["at_synthetic_transitions_max"] for w, c in chars.items()},
            "transitions_per_min": {w: c["num_synthetic_transitions"] / (dur / 60.0) for w, c in chars.items()},
            "window_status": {w: [x["status"] for x in c["windows"]] for w, c in chars.items()},
            "task_s": rep["timings"]["total_s"], "task_s_per_min_speech": rep["timings"]["total_s"] / (dur / 60.0),
            "process_s": res["process_s"], "process_cpu_s": res["process_cpu_s"], "video": rep["outputs"]["video"]}


def summed_by_kind(per_input: dict) -> tuple[dict, int, int]:
    """({kind: [met, total]}, met, total) of the checker's figures summed over the inputs."""
    kinds = {}
    for f in per_input.values():
        for k, v in f.get("met_by_kind", {}).items():
            kinds.setdefault(k, [0, 0])
            kinds[k][0] += v["met"]
            kinds[k][1] += v["total"]
    return kinds, sum(m for m, _ in kinds.values()), sum(t for _, t in kinds.values())


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--cache", default=os.environ.get("CONVSYNTH_CACHE", str(REPO / "data_cache")))
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--skip-real", action="store_true", help="only the timing input")
    ap.add_argument("overrides", nargs="*", help="further convsynth overrides (e.g. preset=paper, task.window_s=15)")
    a = ap.parse_args()
    cache = Path(a.cache).resolve()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        inputs, desc = speech_inputs(tmp, a.seconds)
        ov = [f"{k}={v}" for k, v in inputs.items()] + list(a.overrides)
        first = run(ov, cache, tmp / "run0", check=False)   # fits and caches the models
        fps = first["report"]["inputs"]["fps"] if "report" in first else 30.0
        runs = []
        for i in range(a.repeats):
            r = run(ov, cache, tmp / f"run{i + 1}")
            runs.append(figures(r, tmp / f"run{i + 1}", fps))
        per_input = {}
        if not a.skip_real:
            for name, io in real_inputs(tmp).items():
                o = tmp / f"out_{name}"
                r = run([*(f"{k}={v}" for k, v in io.items()), *a.overrides], cache, o, check=False)
                if "report" not in r:
                    per_input[name] = {"success": False, "error": r["summary"].get("error"),
                                       "process_s": r["process_s"]}
                else:
                    per_input[name] = input_figures(r, o)
                print(name, json.dumps(per_input[name].get("met_by_kind", per_input[name].get("error"))), flush=True)
    kinds, met, total = summed_by_kind(per_input)
    pc = kinds.get("PC", [0, 0])
    med = statistics.median(r["process_s"] for r in runs)
    task_med = statistics.median(r["task_total_s"] for r in runs)
    result = {"timing_input": desc, "seconds": a.seconds, "cache": str(cache), "overrides": a.overrides,
              "first_run": {"process_s": first["process_s"],
                            "parts_s": first.get("report", {}).get("timings")},
              "cached_runs": runs, "process_s_median": med, "task_s_median": task_med, "goal_s": GOAL_S,
              "goal_met_by_task_s": task_med <= GOAL_S, "goal_met_by_process_s": med <= GOAL_S,
              "inputs": per_input,
              "summed": {"by_kind": {k: {"met": m, "total": t} for k, (m, t) in kinds.items()},
                         "met_share": met / total if total else None, "pc_share": pc[0] / pc[1] if pc[1] else None,
                         "all_succeed": all(f.get("success") and f.get("frames_as_long_as_audio") for f in per_input.values()),
                         "acceptance_met": bool(per_input) and all(f.get("success") and f.get("frames_as_long_as_audio")
                                                                   for f in per_input.values())
                         and total > 0 and met >= 0.9 * total and pc[0] >= 0.85 * pc[1]}}
    write_result("bench_converse", result, overrides=a.overrides)


if __name__ == "__main__":
    main()
