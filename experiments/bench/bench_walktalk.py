"""Benchmark: Walk the Talk (convsynth_jax.walktalk) on ../shared/data/bandai2 (fixtures if absent).

Reported (goals: docs/decisions.md#walk-the-talk-what-a-good-splice-is; never asserted):
  * one splice (stylize + sync + Eq. 1-2, 300-frame timeline), warm median of 50, and cold;
  * the whole ``walktalk_eval`` task (all single-peak gestures x 3 loops per gait x 3 methods,
    figures included), in-process, after imports;
  * the demo: 2 characters x 60 s per gait (walk and jog), task time after start-up (speech
    annotation, library loading and synthesis included);
  * an ablation of the stylization constant c on joint-limit violations and the per-gait elbow
    correlation (subset of gestures, 3 loops per gait), plus the paper's band alone
    (splice.respect_joint_limits=false) and the old bounce order (splice.bounce_fit=rescale);
  * the elbow-tracking study: every walk and run clip as a loop (24 + 52), every 6th single-peak
    gesture, naive / stylized / stylized+synced: per gait, the correlation over loops of the
    stroke's elbow bend with the loop's, per gesture, plain and partial given the loop's spread
    (elbow.elbow_partial_corr says why), for the default, the old bounce order, the paper's band
    alone and our within-gait option (splice.band_std=gait_min + splice.joint_limit_mode=soft);
  * optionally (--synthesized-dir, the output folder of task=synthesize) the demo with its
    gestures cut from that synthesized conversation.
Joint-limit violations are printed in both readings (limit_metrics.limit_violations: frames with any
DOF out or any hand in the torso; limit_metrics.limit_cells: DOF x frame cells of the spliced arm over
the blended frames, gesturing hand in the torso), each beside the loop alone over the same frames.
Goals: splice < 20 ms warm, eval < 60 s, demo < 10 s. Writes experiments/results/bench_walktalk.json
(--out to name another file there).

    python experiments/bench/bench_walktalk.py [--quick] [--skip-ablation] [--skip-elbow] [--synthesized-dir DIR]
    python experiments/bench/bench_walktalk.py --combined          # every goal for the candidate settings at once

The one-off diagnoses (--elbow-diagnosis, --limits-breakdown, --jerk-coupling, --loop-seams,
--contact-phases) were retired with their findings written in docs/walktalk.md and docs/results.md; the
script at commit e1848f1 still has them, and their results stay in experiments/results/.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import statistics
import tempfile
import time
from pathlib import Path

from convsynth_jax.config import compose, run_task
from convsynth_jax.api import REPO, SHARED_DATA, write_result
from convsynth_jax.walktalk.elbow import gesture_reach
from convsynth_jax.walktalk.evaluate import goal_rows

GOALS = {"splice_warm_ms": 20.0, "eval_s": 60.0, "demo_s": 10.0}


def bench_splice(data_dir: Path) -> dict:
    from convsynth_jax.walktalk.library import load_library
    from convsynth_jax.walktalk.params import WalkTalkParams

    p = WalkTalkParams()
    lib = load_library(p, data_dir, 1, max_gestures=1, single_peak_only=True)
    from convsynth_jax.walktalk.pipeline import splice_gesture

    lc, gc = lib.loops["jog"][0], lib.gestures[0]
    t0 = time.perf_counter()
    splice_gesture(lc, gc, 5.0, 300, p.splice, "stylized+synced")
    cold = time.perf_counter() - t0
    times = []
    for i in range(50):
        t0 = time.perf_counter()
        splice_gesture(lc, gc, 4.0 + 0.01 * i, 300, p.splice, "stylized+synced")
        times.append(time.perf_counter() - t0)
    return {"splice_cold_ms": 1e3 * cold, "splice_warm_ms": 1e3 * statistics.median(times),
            "splice_warm_ms_max": 1e3 * max(times), "timeline_frames": 300}


def bench_eval(data_dir: Path) -> dict:
    cfg = compose(["task=walktalk_eval", f"walktalk.data_dir={data_dir}"])
    with tempfile.TemporaryDirectory() as d:
        t0 = time.perf_counter()
        s = run_task(cfg, d)
        wall = time.perf_counter() - t0
    return {"eval_s": wall, "eval_load_s": s["load_seconds"], "eval_splice_metrics_s": s["eval_seconds"],
            "eval_splices": s["splices"], "eval_gestures": s["gestures"], "per_gait_method": s["per_gait_method"],
            "limits_in_sample_violation": s["limits_in_sample_violation"], "loop_contact_frac": s["loop_contact_frac"],
            "joint_limit_readings": s["joint_limit_readings"], "limit_table_clips": s["limit_table_clips"]}


def bench_demo(data_dir: Path, synthesized_dir: str | None = None) -> dict:
    out = {}
    runs = [(["walk"], []), (["walk", "jog"], [])]
    if synthesized_dir:
        runs.append((["walk", "jog"], ["task.gesture_source=synthesized", f"task.synthesized_dir={synthesized_dir}"]))
    for gaits, extra in runs:
        cfg = compose(["task=walktalk_demo", f"walktalk.data_dir={data_dir}", f"task.gaits=[{','.join(gaits)}]", *extra])
        with tempfile.TemporaryDirectory() as d:
            t0 = time.perf_counter()
            s = run_task(cfg, d)
            wall = time.perf_counter() - t0
        key = "+".join(gaits) + (" synthesized" if extra else "")
        out[key] = {"demo_s": wall, "synthesized": s.get("synthesized"), "speech_s": s["speech_seconds"], "load_s": s["load_seconds"],
                    "synthesis_s": s["synthesis_seconds"], "gestures_spliced": s["gestures_spliced"],
                    "single_peak_contact_rate": s["single_peak_contact_rate"], "shift_range_s": s["shift_range_s"]}
    return out


def bench_ablation(data_dir: Path) -> list[dict]:
    from convsynth_jax.walktalk.evaluate import EvalParams, run_evaluation, summarize
    from convsynth_jax.walktalk.library import load_library
    from convsynth_jax.walktalk.params import WalkTalkParams

    rows = []
    base = WalkTalkParams()
    lib = load_library(base, data_dir, 3, single_peak_only=True)
    lib.gestures = lib.gestures[::5]
    variants = [(f"c={c}", {"c": c}) for c in (1.0, 1.5, 2.0, 3.0, 5.0)]
    variants += [("c=3.0 paper band (respect_joint_limits=false)", {"respect_joint_limits": False}),
                 ("c=3.0 bounce_fit=rescale", {"bounce_fit": "rescale"}),
                 ("c=3.0 joint_limit_mode=soft", {"joint_limit_mode": "soft"}),
                 ("c=3.0 band_std=gait_min + joint_limit_mode=soft", {"band_std": "gait_min", "joint_limit_mode": "soft"})]
    for name, kw in variants:
        p = dataclasses.replace(base, splice=dataclasses.replace(base.splice, **kw))
        df = run_evaluation(lib, p, EvalParams(methods=("naive", "stylized+synced")))
        for r in summarize(df):
            if r["gait"] != "all":
                rows.append({"variant": name, "c": p.splice.c, "gait": r["gait"], "method": r["method"],
                             "violation_frac_mean": r["violation_frac_mean"],
                             "loop_violation_frac_mean": r["loop_violation_frac_mean"],
                             "limit_cell_frac_mean": r["limit_cell_frac_mean"],
                             "hand_in_torso_gesturing_frac_mean": r["hand_in_torso_gesturing_frac_mean"],
                             "loop_limit_cell_frac_mean": r["loop_limit_cell_frac_mean"],
                             "max_jerk_ratio_median": r["max_jerk_ratio_median"],
                             "jerk_ratio_le_2_rate": r["jerk_ratio_le_2_rate"],
                             "dof_within_csigma_rate": r["dof_within_csigma_rate"],
                             "peak_in_contact_rate": r["peak_in_contact_rate"],
                             "elbow_corr_per_gesture_mean": r["elbow_corr_per_gesture_mean"]})
    return rows


def bench_elbow(data_dir: Path) -> dict:
    from convsynth_jax.walktalk.elbow import elbow_tracking, elbow_tracking_summary
    from convsynth_jax.walktalk.library import load_library
    from convsynth_jax.walktalk.params import WalkTalkParams

    p = WalkTalkParams()
    t0 = time.perf_counter()
    lib = load_library(p, data_dir, 10_000, single_peak_only=True)   # every walk and run clip as a loop
    df = elbow_tracking(lib, p, gestures=lib.gestures[::6])
    out = {"seconds": time.perf_counter() - t0, "skipped_clips": lib.skipped,
           "per_gait_method": elbow_tracking_summary(df)}
    # the old bounce order (rescaled into the band a second time), synced only
    old = dataclasses.replace(p, splice=dataclasses.replace(p.splice, bounce_fit="rescale"))
    df = elbow_tracking(lib, old, gestures=lib.gestures[::6], methods=("stylized+synced",))
    out["bounce_fit_rescale"] = elbow_tracking_summary(df)
    # the paper's band alone (no range-of-motion cut)
    paper = dataclasses.replace(p, splice=dataclasses.replace(p.splice, respect_joint_limits=False))
    df = elbow_tracking(lib, paper, gestures=lib.gestures[::6], methods=("stylized", "stylized+synced"))
    out["paper_band"] = elbow_tracking_summary(df)
    # our option for within-gait tracking: the gait's narrowest band, soft range-of-motion limit
    opt = dataclasses.replace(p, splice=dataclasses.replace(p.splice, band_std="gait_min", joint_limit_mode="soft"))
    df = elbow_tracking(lib, opt, gestures=lib.gestures[::6], methods=("stylized", "stylized+synced"))
    out["gait_min_soft"] = elbow_tracking_summary(df)
    return out


COMBINED = {
    "paper defaults": {},
    "gait_min + soft": {"band_std": "gait_min", "joint_limit_mode": "soft"},
    "gait_min + soft + coupling 0.25": {"band_std": "gait_min", "joint_limit_mode": "soft", "rescale_coupling": 0.25},
    "gait_min + soft + coupling 0.5": {"band_std": "gait_min", "joint_limit_mode": "soft", "rescale_coupling": 0.5},
    "gait_min + soft + coupling 1": {"band_std": "gait_min", "joint_limit_mode": "soft", "rescale_coupling": 1.0},
}


def combined(data_dir: Path, every: int = 6, settings: dict | None = None) -> dict:
    """One pass over every splice goal for the candidate settings (:data:`COMBINED`: the
    paper's defaults, our within-gait options band_std=gait_min + joint_limit_mode=soft, and those
    with splice.rescale_coupling 0.25 / 0.5 / 1), on two libraries:

    * ``eval``: the walktalk_eval setup (3 loops per gait, every single-peak gesture), the one the
      acceptance figures come from (jerk, limits, contact, shifts, +- c sigma);
    * ``all_loops``: every walk and run clip as a loop (24 + 52), every ``every``-th single-peak
      gesture: the within-gait elbow correlation over many loops (of the evaluation's rows, and of
      the peak-placed study elbow.elbow_tracking used by the earlier figures), and the other goals
      again on these loops (with band_std=gait_min the band is the gait's narrowest over the loops
      loaded, so it differs between the two libraries).

    Also both joint-limit readings of the sources themselves, unmodified (limit_metrics.source_readings,
    limit_metrics.in_sample_violations) and the calibrated torso radius; and the price of each setting,
    the gesture's reach at the stroke peak (:func:`gesture_reach`, every 4th gesture, the eval's
    loops)."""
    from convsynth_jax.walktalk.elbow import elbow_tracking, elbow_tracking_summary
    from convsynth_jax.walktalk.evaluate import EvalParams, torso_radius
    from convsynth_jax.walktalk.library import dof_limits, load_library
    from convsynth_jax.walktalk.limit_metrics import in_sample_violations, source_readings
    from convsynth_jax.walktalk.params import WalkTalkParams

    settings = COMBINED if settings is None else settings
    p, ep = WalkTalkParams(), EvalParams()
    t0 = time.perf_counter()
    out: dict = {"settings": settings}
    lib = load_library(p, data_dir, ep.loops_per_gait, single_peak_only=True)
    radius = torso_radius(lib, ep)
    scored = dof_limits(lib, ep.limit_percentiles, ep.limit_tolerance_deg)
    out["torso_radius_cm"] = radius
    out["sources_in_sample"] = in_sample_violations(lib, scored, radius)
    out["sources_eval"] = source_readings(lib, scored, radius)
    out["eval"], _ = goal_rows(lib, p, settings)
    variants = {"naive": (p.splice, "naive")}
    variants.update({name: (dataclasses.replace(p.splice, **kw), "stylized+synced") for name, kw in settings.items()})
    base = next(iter(settings))
    out["reach"] = gesture_reach(lib, p, variants, base)   # the price: the gesture's size at the stroke peak
    out["eval_seconds"] = time.perf_counter() - t0
    lib = load_library(p, data_dir, 10_000, single_peak_only=True)
    lib.gestures = lib.gestures[::every]
    out["sources_all_loops"] = source_readings(lib, scored, radius)
    out["all_loops"], _ = goal_rows(lib, p, settings)
    df = elbow_tracking(lib, p, variants=variants)
    out["elbow_study"] = elbow_tracking_summary(df)
    out["all_loops_gestures"] = len(lib.gestures)
    out["all_loops_loops"] = {g: len(v) for g, v in lib.loops.items()}
    out["seconds"] = time.perf_counter() - t0
    return out


def print_combined(res: dict) -> None:
    pct = "{:.2%}".format
    print(f"torso radius {res['torso_radius_cm']:.2f} cm")
    for part in ("eval", "all_loops"):
        print(f"\n{part}: | setting | gait | jerk > 2x (worst) | contact | shifts | within c sigma | per frame "
              "(loop alone; introduced; naive) | per cell (introduced; naive) + hand in torso | elbow plain / partial |")
        for r in res[part]:
            f, c = r["limits_per_frame"], r["limits_per_cell"]
            print(f"| {r['setting']} | {r['gait']} | {r['jerk_over_2x']}/{r['splices']} ({r['jerk_ratio_max']:.2f}) | "
                  f"{pct(r['peak_in_contact_rate'])} | [{r['shift_min_s']:.3f}, {r['shift_max_s']:.3f}] | "
                  f"{pct(r['dof_within_csigma_rate'])} | {pct(f['value'])} ({pct(f['loop_alone'])}; "
                  f"{pct(f['introduced'])}; {pct(f['naive'])}) | {pct(c['value'])} ({pct(c['introduced'])}; "
                  f"{pct(c['naive'])}) + {pct(c['hand_in_torso'])} | {r['elbow_plain']:.2f} / {r['elbow_partial']:.2f} |")
    for r in res.get("reach", []):
        print(f"reach {r['gait']} {r['variant']}: median {r['reach_cm_median']:.1f} cm, "
              f"x{r['ratio_to_base_median']:.2f} of {r['base']}")
    for r in res["elbow_study"]:
        if r["gait"] != "all":
            print(f"elbow study {r['gait']} {r['method']}: plain {r['elbow_corr_per_gesture_mean']:.3f}, partial "
                  f"{r['elbow_partial_corr_per_gesture_mean']:.3f} ({r['loops']} loops, {r['gestures']} gestures)")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--skip-ablation", action="store_true")
    ap.add_argument("--skip-elbow", action="store_true")
    ap.add_argument("--quick", action="store_true", help="= --skip-ablation --skip-elbow")
    ap.add_argument("--synthesized-dir", default=None, help="output folder of task=synthesize: also time the demo "
                    "with gestures from that synthesized conversation")
    ap.add_argument("--out", default="bench_walktalk.json", help="file name under experiments/results/")
    ap.add_argument("--combined", action="store_true", help="only every goal for the candidate settings "
                    "(writes experiments/results/bench_walktalk_combined.json)")
    a = ap.parse_args()
    if a.quick:
        a.skip_ablation = a.skip_elbow = True
    data_dir = SHARED_DATA / "bandai2" / "bvh"
    if not data_dir.is_dir():
        data_dir = REPO / "tests" / "data" / "walktalk"
    import jax

    result = {"machine": {"platform": platform.platform(), "python": platform.python_version(),
                          "jax": jax.__version__, "devices": [str(d) for d in jax.devices()]},
              "data_dir": str(data_dir), "goals": GOALS}
    if a.combined:
        result.update(combined(data_dir))
        result["load_average"] = list(os.getloadavg())
        write_result("bench_walktalk_combined", result)
        return print_combined(result)
    result.update(bench_splice(data_dir))
    result.update(bench_eval(data_dir))
    result["demo"] = bench_demo(data_dir, a.synthesized_dir)
    if not a.skip_ablation:
        result["ablation_c"] = bench_ablation(data_dir)
    if not a.skip_elbow:
        result["elbow_tracking"] = bench_elbow(data_dir)
    result["met"] = {"splice": result["splice_warm_ms"] < GOALS["splice_warm_ms"],
                     "eval": result["eval_s"] < GOALS["eval_s"],
                     "demo": all(v["demo_s"] < GOALS["demo_s"] for v in result["demo"].values())}
    result["load_average"] = list(os.getloadavg())
    write_result(Path(a.out).stem, result)
    print(json.dumps({k: v for k, v in result.items() if k not in ("per_gait_method", "ablation_c", "elbow_tracking")},
                     indent=2, default=float))
    print_table(result)
    for key in ("per_gait_method", "bounce_fit_rescale", "paper_band", "gait_min_soft"):
        for r in result.get("elbow_tracking", {}).get(key, []):
            print(key, {k: (round(v, 3) if isinstance(v, float) else v) for k, v in r.items()})
    if "ablation_c" in result:
        for r in result["ablation_c"]:
            print({k: (round(v, 4) if isinstance(v, float) else v) for k, v in r.items()})


def print_table(result: dict) -> None:
    """The per-gait table: violations in both readings with the loop-alone baselines, elbow
    correlations (3 evaluation loops), peak in contact, shifts, jerk, foot slide."""
    pct = "{:.2%}".format
    print("\n| gait | method | peak in contact | shifts (s) | violations, frames (loop alone) | violations, "
          "cells (loop alone) | gesturing hand in torso (loop alone) | jerk ratio median (max) | foot slide max cm "
          "| elbow corr. plain / partial (3 loops) |")
    print("|---" * 10 + "|")
    for r in result["per_gait_method"]:
        if r["gait"] == "all":
            continue
        print(f"| {r['gait']} | {r['method']} | {pct(r['peak_in_contact_rate'])} | "
              f"[{r['shift_min_s']:.3f}, {r['shift_max_s']:.3f}] | {pct(r['violation_frac_mean'])} "
              f"({pct(r['loop_violation_frac_mean'])}) | {pct(r['limit_cell_frac_mean'])} "
              f"({pct(r['loop_limit_cell_frac_mean'])}) | {pct(r['hand_in_torso_gesturing_frac_mean'])} "
              f"({pct(r['loop_hand_in_torso_gesturing_frac_mean'])}) | {r['max_jerk_ratio_median']:.2f} "
              f"({r['max_jerk_ratio_max']:.2f}) | {r['foot_slide_cm_max']:.2f} | "
              f"{r['elbow_corr_per_gesture_mean']:.2f} / {r['elbow_partial_corr_per_gesture_mean']:.2f} |")
    for r in result.get("joint_limit_readings", []):
        f, c = r["per_frame"], r["per_cell"]
        print(f"joint limits {r['gait']} {r['method']}: per frame {pct(f['value'])} (loop alone {pct(f['loop_alone'])}, "
              f"naive {pct(f['naive'])}) met={r['met_per_frame']}; per cell {pct(c['value'])} + hand in torso "
              f"{pct(c['hand_in_torso'])} (naive {pct(c['naive'])} + {pct(c['hand_in_torso_naive'])}) met={r['met_per_cell']}")
    for r in result.get("elbow_tracking", {}).get("per_gait_method", []):
        print(f"elbow, all loops: {r['gait']} {r['method']} ({r['loops']} loops, {r['gestures']} gestures): plain "
              f"{r['elbow_corr_per_gesture_mean']:.3f} (median {r['elbow_corr_per_gesture_median']:.3f}), partial "
              f"{r['elbow_partial_corr_per_gesture_mean']:.3f} (median {r['elbow_partial_corr_per_gesture_median']:.3f}),"
              f" slope {r['elbow_slope_per_gesture_median']:.2f}")


if __name__ == "__main__":
    main()
