"""Which leave-one-out seams come from a planted marker-swap glitch (docs/decisions.md#marker-swap-glitches-and-touching-clauses).

    python experiments/analysis/seam_glitches.py [--folds N | --fold-list 6 ...] [--conditions no_hp ...]
        [--cache DIR] [--name seam_glitches] [overrides ...]

Runs the leave-one-out sweep (``run_fold`` per fold and condition, both characters, as
``experiments/bench/bench_loo.py`` does) with ``search.matching=labels`` on the default synthetic
corpus, keeping each window's ``WindowResult`` (a thin wrapper around the system). For every
synthesized window and every synthetic transition arriving at output frame t (a seam): its seam ratio,
the project's measure (``evaluation.metrics.seam_ratio`` with this one transition: the largest
root-relative joint acceleration within ``SEAM_RADIUS`` frames of t over the ground-truth window's
largest), and whether its blend span touches a planted glitch, raw or in the continuation, nominal or
played (the detector: ``convsynth_jax/synth/seam_glitches.py``).

Also counted: every output frame whose raw source is a glitch frame (a glitch played inside a clip,
along an original transition, seam or not). Results: ``experiments/results/<name>.json`` and ``.md``
(with a manifest), and ``<name>_seams.csv`` with every seam; ``<name>.partial.csv`` is rewritten after
every fold so that a cut-short run keeps what it did.
"""
import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "experiments" / "bench"))
sys.path.insert(0, str(REPO))

from _bench import RESULTS, write, write_markdown  # noqa: E402

from convsynth_jax.config import default_params  # noqa: E402
from convsynth_jax.evaluation import metrics  # noqa: E402
from convsynth_jax.evaluation.loo import loo_cases  # noqa: E402
from convsynth_jax.kinematics import forward_kinematics  # noqa: E402
from convsynth_jax.synth.seam_glitches import (glitch_frames, seam_glitch_counts, touching_rows,  # noqa: E402
                                               window_seam_glitches)
from convsynth_jax.systems.base import make_system  # noqa: E402
from convsynth_jax.systems.playback import clip_name  # noqa: E402
from convsynth_jax.api import annotated_corpus, cache_dir  # noqa: E402


def window_seams(res, gt_motion, motions: dict, glitches: dict, max_step: float, fps: float) -> tuple[list, int]:
    """(one dict per seam, output frames whose raw source is a glitch frame) of one window, each seam
    with its seam ratio against the ground-truth window (``evaluation.metrics.seam_ratio``)."""
    cache = {}

    def ratio(t: int) -> float:
        if not cache:
            cache["pos"] = np.asarray(forward_kinematics(res.motion), np.float64)
            cache["gt"] = np.asarray(forward_kinematics(gt_motion), np.float64)
        return metrics.seam_ratio(cache["pos"], cache["gt"], fps, [t])

    return window_seam_glitches(res, motions, glitches, max_step, seam_ratio=ratio)


def summarize(seams: pd.DataFrame, windows: pd.DataFrame | None, top: int) -> dict:
    """The figures of a sweep; ``windows`` None: those counted per window are None (not kept)."""
    if windows is None:
        out = summarize(seams, pd.DataFrame({"frames": [], "frames_from_glitch": []}), top)
        return {**out, **{k: None for k in ("windows_synthesized", "windows_from_glitch_frames", "output_frames",
                                            "output_frames_from_glitch_frames")}}
    ok = seams.dropna(subset=["seam_ratio"]) if len(seams) else seams
    worst = ok.sort_values("seam_ratio", ascending=False).head(top) if len(ok) else ok
    cols = ["fold", "condition", "character", "window", "t", "seam_ratio", "left_clip", "left_frame", "new_clip",
            "new_frame", "touches_glitch_played", "touches_glitch_nominal"]
    return {
        "windows_synthesized": int(len(windows)),
        "windows_from_glitch_frames": int((windows["frames_from_glitch"] > 0).sum()) if len(windows) else 0,
        "output_frames": int(windows["frames"].sum()) if len(windows) else 0,
        "output_frames_from_glitch_frames": int(windows["frames_from_glitch"].sum()) if len(windows) else 0,
        **seam_glitch_counts(seams),
        "seam_ratio_max_touching_glitch_played": float(ok.loc[ok["touches_glitch_played"], "seam_ratio"].max())
        if len(ok) and ok["touches_glitch_played"].any() else None,
        "worst_seams": worst[cols].to_dict(orient="records") if len(worst) else [],
    }


def report_touching(name: str, overrides) -> None:
    """<name>_touching.{json,md}: where the glitch frames of every seam touching one lie (from
    <name>_seams.csv and <name>.json of a finished sweep)."""
    import json

    res = json.loads((RESULTS / f"{name}.json").read_text())
    seams = read_seams(RESULTS / f"{name}_seams.csv")
    rows = touching_rows(seams, int(res["blend_frames"]), int(res["seam_radius"]))
    seen = {(r["fold"], r["condition"], r["character"], r["window"], r["t"]) for r in rows}
    in_measure = {(r["fold"], r["condition"], r["character"], r["window"], r["t"]) for r in rows if r["in_seam_measure"]}
    summary = {"source": f"{name}_seams.csv", "seams_total": int(len(seams)), "seams_touching_glitch_any": len(seen),
               "seams_with_a_glitch_frame_in_the_seam_measure": len(in_measure),
               "seams_with_a_played_continuation_glitch": len({(r["fold"], r["condition"], r["character"], r["window"],
                                                                r["t"]) for r in rows if r["where"] == "continuation"}),
               "glitch_frames": rows}
    write(f"{name}_touching", summary, overrides=overrides)
    lines = [f"Seams of `{name}` whose blend span touches a planted glitch ({len(seen)} of {len(seams)}; "
             f"{len(in_measure)} with a glitch frame the seam measure reads: within {int(res['seam_radius']) + 1} frames), one row per "
             "glitch frame; offset: output frame minus the transition's.", "",
             "| fold | condition | character | window | t | seam ratio | where | clip:frame | offset | in seam measure |",
             "|---" * 10 + "|"]
    for r in rows:
        lines.append(f"| {r['fold']} | {r['condition']} | {r['character']} | {r['window']} | {r['t']} | "
                     f"{r['seam_ratio']:.2f} | {r['where']} | {r['clip']}:{r['frame']} | "
                     f"{'?' if r['offset'] is None else r['offset']} | {r['in_seam_measure']} |")
    write_markdown(f"{name}_touching", lines, overrides=overrides)


def header(params, corpus, overrides, folds, conditions) -> dict:
    return {"overrides": overrides, "folds": folds, "conditions": conditions,
            "continuation_max_step_deg": float(params.synth.continuation_max_step_deg),
            "glitch_max_step_deg": float(params.graph.glitch_max_step_deg),
            "blend_frames": int(params.synth.blend_frames), "seam_radius": metrics.SEAM_RADIUS,
            "planted_glitches": int(len(pd.read_csv(Path(corpus.root) / "glitches.csv")))}


def finish(name: str, seams: pd.DataFrame, windows: pd.DataFrame | None, head: dict, top: int, t0: float,
           note: str = "") -> None:
    """<name>.json/.md, <name>_seams.csv and <name>_touching.{json,md}."""
    seams.to_csv(RESULTS / f"{name}_seams.csv", index=False)
    overrides, folds, conditions = head["overrides"], head["folds"], head["conditions"]
    r = {**head, **summarize(seams, windows, top), "note": note or None,
         "seconds": time.perf_counter() - t0, "load_avg_1_5_15_at_end": list(os.getloadavg())}
    write(name, r, overrides=overrides)

    def n(x):
        return "not kept" if x is None else x

    lines = [f"Seams of the leave-one-out sweep ({len(folds)} folds x {len(conditions)} conditions, both characters; "
             f"overrides `{' '.join(overrides)}`; `graph.glitch_max_step_deg` {r['glitch_max_step_deg']:g}, "
             f"`synth.continuation_max_step_deg` {r['continuation_max_step_deg']:g}, blend {r['blend_frames']} frames) "
             f"against the {r['planted_glitches']} planted glitches of the corpus (`glitches.csv`). {note}", "",
             "| windows | output frames | frames played from a glitch | seams | seams touching a glitch (played) | "
             "(nominal continuation) | seams > 1 |", "|---" * 7 + "|",
             f"| {n(r['windows_synthesized'])} | {n(r['output_frames'])} | {n(r['output_frames_from_glitch_frames'])} "
             f"({n(r['windows_from_glitch_frames'])} windows) | {r['seams_total']} | {r['seams_touching_glitch_played']} | "
             f"{r['seams_touching_glitch_nominal']} | {r['seams_over_1']} |", "",
             "Worst seams:", "", "| fold | condition | character | window | t | seam ratio | left clip:frame | "
             "new clip:frame | glitch |", "|---" * 9 + "|"]
    for w in r["worst_seams"]:
        lines.append(f"| {w['fold']} | {w['condition']} | {w['character']} | {w['window']} | {w['t']} | "
                     f"{w['seam_ratio']:.2f} | {w['left_clip']}:{w['left_frame']} | {w['new_clip']}:{w['new_frame']} | "
                     f"{'yes' if w['touches_glitch_played'] else 'no'} |")
    write_markdown(name, lines, overrides=overrides)
    report_touching(name, overrides)


def read_seams(path: Path) -> pd.DataFrame:
    cols = ("glitch_raw", "glitch_continuation_nominal", "glitch_continuation_played")
    d = pd.read_csv(path, dtype={c: str for c in cols})
    for c in cols:
        d[c] = d[c].fillna("")
    return d


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--folds", type=int, default=None, help="the first N folds (default: all)")
    ap.add_argument("--fold-list", type=int, nargs="*", default=None, help="these folds instead")
    ap.add_argument("--conditions", nargs="*", default=None, help="default: all of the system's")
    ap.add_argument("--cache", default=str(REPO / "data_cache"))
    ap.add_argument("--name", default="seam_glitches")
    ap.add_argument("--top", type=int, default=10)
    ap.add_argument("--touching-only", action="store_true",
                    help="only write <name>_touching.{json,md} from a finished sweep's <name>_seams.csv")
    ap.add_argument("--from-partial", action="store_true",
                    help="write the results of a cut-short sweep from its <name>.partial*.csv (same overrides)")
    ap.add_argument("overrides", nargs="*", help="config overrides after search.matching=labels")
    args = ap.parse_args()
    if args.touching_only:
        report_touching(args.name, ["search.matching=labels", *args.overrides])
        sys.exit(0)
    t0 = time.perf_counter()
    overrides = ["search.matching=labels", *args.overrides]
    params = default_params([f"cache_dir={args.cache}", "progress=false", *overrides])
    if args.from_partial:  # a cut-short sweep: its folds so far, from the files rewritten after each fold
        from convsynth_jax.api import open_corpus

        seams = read_seams(RESULTS / f"{args.name}.partial.csv")
        wpath = RESULTS / f"{args.name}.partial_windows.csv"
        windows = pd.read_csv(wpath) if wpath.exists() else None
        done = sorted(int(f) for f in seams["fold"].unique())
        conds = args.conditions or list(make_system(params, params.system).conditions)
        finish(args.name, seams, windows, header(params, open_corpus(params), overrides, done, conds), args.top, t0,
               note=f"Cut short: folds {done} of the sweep only.")
        sys.exit(0)
    fps = float(params.features.fps)
    system = make_system(params, params.system)
    corpus, ann = annotated_corpus(params)
    glitches = glitch_frames(Path(corpus.root) / "glitches.csv", clip_name)
    max_step = float(params.synth.continuation_max_step_deg)
    cache = cache_dir(params)
    folds = args.fold_list if args.fold_list else list(range(args.folds or len(corpus.sessions)))
    conditions = args.conditions or list(system.conditions)
    seam_rows, window_rows, seconds = [], [], {}
    for fold in folds:
        models: dict = {}
        for cond in conditions:
            tf = time.perf_counter()
            for case in loo_cases(system, ann, params, fold, cond, cache_dir=cache, models=models):
                res, win = case.result, case.input
                if res is None or not res.success or res.motion is None:
                    continue
                seams, n_glitch = window_seams(res, case.ground_truth, case.model.motions, glitches, max_step, fps)
                key = {"fold": fold, "session": win.session, "condition": case.condition, "character": win.character,
                       "role": win.role, "window": case.window.index}
                window_rows.append({**key, "frames": len(res.source_frame), "frames_from_glitch": n_glitch,
                                    "seams": len(seams)})
                seam_rows += [{**key, **s} for s in seams]
            seconds[f"{fold}/{cond}"] = time.perf_counter() - tf
            print(f"fold {fold} {cond}: {seconds[f'{fold}/{cond}']:.1f} s, {len(seam_rows)} seams so far, "
                  f"{sum(s['touches_glitch_played'] for s in seam_rows)} touching a glitch", flush=True)
        pd.DataFrame(seam_rows).to_csv(RESULTS / f"{args.name}.partial.csv", index=False)
        pd.DataFrame(window_rows).to_csv(RESULTS / f"{args.name}.partial_windows.csv", index=False)
    seams = pd.DataFrame(seam_rows)
    windows = pd.DataFrame(window_rows)
    for suffix in (".partial.csv", ".partial_windows.csv"):
        if (RESULTS / f"{args.name}{suffix}").exists():
            (RESULTS / f"{args.name}{suffix}").unlink()
    finish(args.name, seams, windows, header(params, corpus, overrides, folds, conditions), args.top, t0)
