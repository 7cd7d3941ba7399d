"""Benchmark: the motion-graph search on real speech, per preset.

The real recordings of ``../shared/data/speech`` (acoustic_corpus.wav 26.7 s, cold_corpus.wav 25.7 s,
word-level TextGrids) are annotated by the audio pipeline (clauses, responses, hesitations, F0 peaks)
and cut into 15 s speaker windows starting at 0 and 10 s (two per file, four windows) with a silent
partner. Each window is synthesized for each character by a motion graph fitted on the whole default
synthetic corpus (every session; the graphs are cached under ``--cache``). Per preset (paper,
quality) it reports the share of windows solved (a path meeting every constraint by the checker; a best-effort path
counts as unsolved), the share of clause (PC) constraints and of all constraints met by the
independent checker (``search/check.py``, through the retiming warp where there is one; a window
without a path meets none), and the output's mean jerk and seam ratio (``evaluation/metrics.py``;
no ground truth exists for this speech, so the seam ratio's reference is the first 15 s of the
character's first corpus recording).

    python experiments/bench/bench_real_speech.py [--cache DIR] [--presets paper quality]
        [--overrides search.retime_factor=0.3 ...] [--characters female] [--name bench_real_speech]

Writes experiments/results/<name>.json (with a manifest).
"""
import argparse
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from convsynth_jax.annotate.audio import annotate_audio
from convsynth_jax.config import default_params
from convsynth_jax.evaluation import metrics
from convsynth_jax.evaluation.loo import fit_fold
from convsynth_jax.evaluation.windows import Window, window_segments
from convsynth_jax.io import load_audio, load_transcript
from convsynth_jax.kinematics import forward_kinematics
from convsynth_jax.search.check import check_path
from convsynth_jax.synth.pipeline import synthesize_character
from convsynth_jax.systems.motion_graph import clip_name
from convsynth_jax.api import annotated_corpus, cache_dir, make_configured_system, REPO, SHARED_DATA, write_result

FILES = ("acoustic_corpus", "cold_corpus")
STARTS = (0.0, 10.0)
LENGTH = 15.0


def speech_windows(speech: Path, annotate) -> list:
    """[(name, own segments relative to the window)] of the real recordings."""
    out = []
    for name in FILES:
        words = load_transcript(speech / f"{name}.TextGrid")
        segs = annotate_audio(words, load_audio(speech / f"{name}.wav"), annotate)
        for s in STARTS:
            out.append((f"{name}@{s:g}", window_segments(segs, Window(0, s, s + LENGTH))))
    return out


def positions(motion) -> np.ndarray:
    return np.asarray(forward_kinematics(motion), np.float64)


def run_preset(preset: str, cache: str, overrides: list, characters, seed: int) -> dict:
    params = default_params([f"preset={preset}", f"cache_dir={cache}", "progress=false", *overrides])
    _, ann = annotated_corpus(params)
    system = make_configured_system(params)
    fitted = fit_fold(system, ann, "", "all", cache_dir(params))   # held out: none (every session)
    clip_audio = {clip_name(s, r): (a.own, a.partner) for s, d in ann.items() for r, a in d.items()}
    fps = params.fps
    n = int(round(LENGTH * fps))
    empty = pd.DataFrame(columns=["kind", "start", "peak", "end", "text"])
    rows = []
    for name, own in speech_windows(SHARED_DATA / "speech", params.annotate):
        for char in characters or sorted(fitted):
            model = fitted[char]
            ref = next(a.motion for d in ann.values() for a in d.values() if a.character == char)
            ref_pos = positions(ref)[:n]
            t0 = time.perf_counter()
            res = synthesize_character(model.graph, model.motions, own, empty, n, params.search, params.synth,
                                       seed=seed)
            row = {"window": name, "character": char, "seconds": time.perf_counter() - t0,
                   "success": bool(res.success), "best_effort": bool(res.best_effort), "failure": res.failure}
            pcs = int((own["kind"] == "PC").sum())
            if res.motion is not None:
                chk = check_path(res.source_clip, res.source_frame, clip_audio, own, empty, fps,
                                 params.search.tolerance, params.search.use_lr, params.search.use_hp,
                                 matching=params.search.matching, warp=res.warp)
                d = chk["details"]
                pos = positions(res.motion)
                row.update({
                    "checker_met": chk["met"], "checker_total": chk["total"],
                    "checker_pc_met": sum(x["met"] for x in d if x["kind"] == "PC"),
                    "checker_pc_total": sum(x["kind"] == "PC" for x in d),
                    "search_claims_match_checker": (res.claimed == {(x["kind"], int(x["start"]), int(x["end"])):
                                                                    bool(x["met"]) for x in d}
                                                    if res.claimed is not None else None),
                    "warp_knots": len(res.warp[0]) - 2 if res.warp is not None else 0,
                    "unmet": [{k: x[k] for k in ("kind", "start", "end", "peak")} for x in d if not x["met"]],
                    "jerk": metrics.mean_jerk(pos, fps), "max_jump": float(metrics.max_frame_jump(pos).max()),
                    "seam_ratio": metrics.seam_ratio(pos, ref_pos, fps, res.synthetic_at),
                    "num_synthetic_transitions": len(res.synthetic_at)})
            else:
                row.update({"checker_met": 0, "checker_total": None, "checker_pc_met": 0,
                            "checker_pc_total": None})
            row["input_pc"] = pcs
            rows.append(row)
            print(f"{preset} {name} {char}: success={row['success']} best_effort={row['best_effort']} "
                  f"PC {row['checker_pc_met']}/{row.get('checker_pc_total')} all {row['checker_met']}/"
                  f"{row.get('checker_total')} {row['seconds']:.1f} s", flush=True)
    df = pd.DataFrame(rows)
    done = df[df["checker_total"].notna()]
    # solved: a path meeting every constraint, by the checker (a best-effort path never counts)
    df["solved"] = df["success"] & ~df["best_effort"] & (df["checker_met"] == df["checker_total"])
    pc_total = int(df["checker_pc_total"].fillna(df["input_pc"]).sum())
    all_total = int(done["checker_total"].sum()) if len(done) else 0
    return {
        "windows": len(df), "solved": int(df["solved"].sum()), "solved_share": float(df["solved"].mean()),
        "best_effort": int(df["best_effort"].sum()),
        "with_motion": int(len(done)),
        "pc_constraints_met_share": float(df["checker_pc_met"].sum() / max(pc_total, 1)),
        "constraints_met_share_with_motion": float(done["checker_met"].sum() / max(all_total, 1)),
        "mean_jerk": float(done["jerk"].mean()) if len(done) else None,
        "mean_max_jump": float(done["max_jump"].mean()) if len(done) else None,
        "median_seam_ratio": float(done["seam_ratio"].median()) if len(done) else None,
        "mean_seconds": float(df["seconds"].mean()),
        "rows": df.replace({np.nan: None}).to_dict(orient="records"),
    }


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cache", default=str(REPO / "data_cache"), help="cache_dir: corpus, annotation, graphs")
    ap.add_argument("--presets", nargs="+", default=["paper", "quality"])
    ap.add_argument("--overrides", nargs="*", default=[], help="config overrides for every preset")
    ap.add_argument("--characters", nargs="*", default=None, help="default: every character")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--name", default="bench_real_speech")
    ap.add_argument("--fit-only", action="store_true", help="only fit (and cache) the graphs")
    args = ap.parse_args()
    if not (SHARED_DATA / "speech").is_dir():
        sys.exit(f"no real speech at {SHARED_DATA / 'speech'}")
    if args.fit_only:
        for p in args.presets:
            prm = default_params([f"preset={p}", f"cache_dir={args.cache}", "progress=false", *args.overrides])
            _, a = annotated_corpus(prm)
            fit_fold(make_configured_system(prm), a, "", "all", cache_dir(prm))
        sys.exit(0)
    out = {"length_s": LENGTH, "starts_s": list(STARTS), "files": list(FILES), "overrides": args.overrides,
           "targets": {"paper_solved_share": 0.5, "quality_pc_constraints_met_share": 0.8}}
    for p in args.presets:
        out[p] = run_preset(p, args.cache, args.overrides, args.characters, args.seed)
    write_result(args.name, out, overrides=args.overrides)
