"""Which leave-one-out seams come from a planted marker-swap glitch (docs/decisions.md#marker-swap-glitches-and-touching-clauses).

    python experiments/analysis/seam_glitches.py [--folds N | --fold-list 6 ...] [--conditions no_hp ...]
        [--cache DIR] [--name seam_glitches] [overrides ...]

Runs the leave-one-out sweep (``run_fold`` per fold and condition, both characters, as
``experiments/bench/bench_loo.py`` does) with ``search.matching=labels`` on the default synthetic
corpus, keeping each window's ``WindowResult`` (a thin wrapper around the system). For every
synthesized window and every synthetic transition arriving at output frame t (a seam):

* its seam ratio, the project's measure (``evaluation.metrics.seam_ratio`` with this one transition:
  the largest root-relative joint acceleration within ``SEAM_RADIUS`` frames of t over the ground-truth
  window's largest);
* the source frames around it: the raw sources of output frames t - B .. t + B - 1 (B =
  ``blend_frames``: the end of the clip the path leaves and the start of the new one) and the
  continuation of the left clip that the blend fades out, frames f + 1 .. f + L of the clip played at
  t - 1 (frame f). L spans the blend and every blend nested into it (a transition arriving before the
  previous blend ended), so it is never shorter than what the realization shows. The continuation is
  counted twice: ``nominal`` (all L frames, up to the clip's end) and ``played`` (stopped where the
  realization holds it, ``synth.realize.continuation_end`` with ``synth.continuation_max_step_deg``;
  the same as nominal when that is 0);
* whether any of those frames is a planted glitch frame (``glitches.csv`` of the corpus: session,
  participant, start_frame <= frame < end_frame) of that source clip.

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
from convsynth_jax.evaluation.loo import recording_threshold_table, run_fold  # noqa: E402
from convsynth_jax.kinematics import forward_kinematics  # noqa: E402
from convsynth_jax.synth.realize import continuation_end  # noqa: E402
from convsynth_jax.systems.base import make_system  # noqa: E402
from convsynth_jax.systems.playback import clip_name  # noqa: E402
from convsynth_jax.tasks.common import annotated_corpus, cache_dir  # noqa: E402


class KeepResults:
    """The system, with every WindowResult it returns kept in ``kept`` (with its WindowInput)."""

    def __init__(self, system):
        self._system = system
        self.kept = []

    def __getattr__(self, name):
        return getattr(self._system, name)

    def synthesize(self, model, win, condition):
        res = self._system.synthesize(model, win, condition)
        self.kept.append((model, win, condition, res))
        return res


def glitch_frames(path: Path) -> dict:
    """clip name -> set of planted glitch frames, from a corpus's glitches.csv."""
    out: dict = {}
    for r in pd.read_csv(path).itertuples():
        out.setdefault(clip_name(r.session, r.participant), set()).update(range(int(r.start_frame), int(r.end_frame)))
    return out


def nested_span(syn: list, m: int, blend: int) -> int:
    """Output frames from transition m on during which the old stream of its blend can still show:
    its own blend, extended by every transition arriving before the running blend ended."""
    end = syn[m] + blend
    for t in syn[m + 1:]:
        if t >= end:
            break
        end = t + blend
    return end - syn[m]


def window_seams(res, gt_motion, motions: dict, glitches: dict, max_step: float, fps: float) -> tuple[list, int]:
    """(one dict per seam, output frames whose raw source is a glitch frame) of one window."""
    clips, frames = list(res.source_clip), [int(f) for f in res.source_frame]
    T, B = len(frames), int(res.blend_frames)
    from_glitch = sum(f in glitches.get(c, ()) for c, f in zip(clips, frames))
    syn = sorted({int(t) for t in (res.synthetic_at or []) if 0 < int(t) < T})
    if not syn:
        return [], from_glitch
    pos = np.asarray(forward_kinematics(res.motion), np.float64)
    gt = np.asarray(forward_kinematics(gt_motion), np.float64)
    out = []
    for m, t in enumerate(syn):
        raw = [(clips[u], frames[u]) for u in range(max(0, t - B), min(T, t + B))]
        c, f = clips[t - 1], frames[t - 1]
        rot = motions[c].rotations
        span = nested_span(syn, m, B)
        nominal_end = min(rot.shape[0] - 1, f + span)
        played_end = min(nominal_end, continuation_end(rot, f, max_step, span))
        g_raw = sorted({(cc, ff) for cc, ff in raw if ff in glitches.get(cc, ())})
        g_nom = sorted(ff for ff in range(f + 1, nominal_end + 1) if ff in glitches.get(c, ()))
        g_play = sorted(ff for ff in range(f + 1, played_end + 1) if ff in glitches.get(c, ()))
        out.append({"t": t, "seam_ratio": metrics.seam_ratio(pos, gt, fps, [t]),
                    "left_clip": c, "left_frame": f, "new_clip": clips[t], "new_frame": frames[t],
                    "continuation_nominal_end": nominal_end, "continuation_played_end": played_end,
                    "glitch_raw": ";".join(f"{cc}:{ff}" for cc, ff in g_raw),
                    "glitch_continuation_nominal": ";".join(map(str, g_nom)),
                    "glitch_continuation_played": ";".join(map(str, g_play)),
                    "touches_glitch_nominal": bool(g_raw or g_nom), "touches_glitch_played": bool(g_raw or g_play)})
    return out, from_glitch


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
        "seams_total": int(len(seams)),
        "seams_touching_glitch_played": int(seams["touches_glitch_played"].sum()) if len(seams) else 0,
        "seams_touching_glitch_nominal": int(seams["touches_glitch_nominal"].sum()) if len(seams) else 0,
        "seams_with_glitch_in_raw_sources": int((seams["glitch_raw"] != "").sum()) if len(seams) else 0,
        "seams_over_1": int((ok["seam_ratio"] > 1).sum()) if len(ok) else 0,
        "seam_ratio_max_touching_glitch_played": float(ok.loc[ok["touches_glitch_played"], "seam_ratio"].max())
        if len(ok) and ok["touches_glitch_played"].any() else None,
        "worst_seams": worst[cols].to_dict(orient="records") if len(worst) else [],
    }


def _frames(cell) -> list:
    return [] if pd.isna(cell) or cell == "" else [x for x in str(cell).split(";") if x]


def touching_rows(seams: pd.DataFrame, blend: int, radius: int) -> list[dict]:
    """Each seam whose blend span touches a glitch, with every glitch frame's place: the output frame
    offset from the transition (u - t; None where another transition of the window lies between, so
    the offset is not known from the seam table) and whether the seam measure reads it (its
    accelerations at |u - t| <= ``radius`` are central differences, so they read |u - t| <= radius + 1).
    ``raw after t``: the new clip's own frames, played by the path at the blend's
    new-source weight; ``raw before t``: the left clip's frames before the transition;
    ``continuation``: the left clip's continuation faded out by the blend."""
    out = []
    keys = ["fold", "condition", "character", "window"]
    for _, s in seams[seams["touches_glitch_nominal"] | seams["touches_glitch_played"]].iterrows():
        ts = sorted(seams.loc[(seams[keys] == s[keys]).all(axis=1), "t"])
        t = int(s["t"])
        places = []
        for item in _frames(s["glitch_raw"]):
            clip, ff = item.rsplit(":", 1)
            ff = int(ff)
            if clip == s["new_clip"] and 0 <= ff - int(s["new_frame"]) < blend:
                k = ff - int(s["new_frame"])
                known = not any(t < x <= t + k for x in ts)
                places.append(("raw after t", clip, ff, k if known else None))
            elif clip == s["left_clip"] and 0 <= int(s["left_frame"]) - ff < blend:
                k = -(int(s["left_frame"]) - ff) - 1
                known = not any(t + k < x < t for x in ts)
                places.append(("raw before t", clip, ff, k if known else None))
            else:
                places.append(("raw", clip, ff, None))
        played = set(_frames(s["glitch_continuation_played"]))
        for ff in _frames(s["glitch_continuation_nominal"]):
            if ff in played:
                places.append(("continuation", s["left_clip"], int(ff), int(ff) - int(s["left_frame"]) - 1))
            else:
                places.append(("continuation, held (not played)", s["left_clip"], int(ff), None))
        for where, clip, ff, k in places:
            out.append({"fold": int(s["fold"]), "condition": str(s["condition"]), "character": str(s["character"]),
                        "window": int(s["window"]), "t": t, "seam_ratio": float(s["seam_ratio"]), "where": where,
                        "clip": clip, "frame": ff, "offset": k,
                        "in_seam_measure": None if k is None else bool(abs(k) <= radius + 1)})
    return out


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
        from convsynth_jax.tasks.common import open_corpus

        seams = read_seams(RESULTS / f"{args.name}.partial.csv")
        wpath = RESULTS / f"{args.name}.partial_windows.csv"
        windows = pd.read_csv(wpath) if wpath.exists() else None
        done = sorted(int(f) for f in seams["fold"].unique())
        conds = args.conditions or list(make_system(params, params.system).conditions)
        finish(args.name, seams, windows, header(params, open_corpus(params), overrides, done, conds), args.top, t0,
               note=f"Cut short: folds {done} of the sweep only.")
        sys.exit(0)
    fps = float(params.features.fps)
    system = KeepResults(make_system(params, params.system))
    corpus, ann = annotated_corpus(params)
    glitches = glitch_frames(Path(corpus.root) / "glitches.csv")
    max_step = float(params.synth.continuation_max_step_deg)
    thresholds = recording_threshold_table(ann, params.annotate)
    cache = cache_dir(params)
    folds = args.fold_list if args.fold_list else list(range(args.folds or len(corpus.sessions)))
    conditions = args.conditions or list(system.conditions)
    seam_rows, window_rows, seconds = [], [], {}
    for fold in folds:
        models: dict = {}
        for cond in conditions:
            tf = time.perf_counter()
            system.kept.clear()
            run_fold(system, ann, fold, cond, params, cache_dir=cache, models=models, thresholds=thresholds)
            for model, win, condition, res in system.kept:
                if not res.success or res.motion is None:
                    continue
                gt = ann[win.session][win.role].motion.slice(win.start_frame, win.start_frame + win.num_frames)
                seams, n_glitch = window_seams(res, gt, model.motions, glitches, max_step, fps)
                key = {"fold": fold, "session": win.session, "condition": condition, "character": win.character,
                       "role": win.role, "window": int(round(win.start_frame / (params.loo.hop * fps)))}
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
