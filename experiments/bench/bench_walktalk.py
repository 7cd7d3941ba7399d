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
    python experiments/bench/bench_walktalk.py --elbow-diagnosis   # why the within-gait elbow figure is low
    python experiments/bench/bench_walktalk.py --limits-breakdown  # where the per-frame joint-limit reading fails
    python experiments/bench/bench_walktalk.py --combined          # every goal for the candidate settings at once
    python experiments/bench/bench_walktalk.py --loop-seams        # what the loops' seam correction does to the arms
    python experiments/bench/bench_walktalk.py --contact-phases  # contact fractions of every loop, both readings
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

from _bench import REPO, RESULTS, SHARED

from convsynth_jax.config import compose, run_task
from convsynth_jax.utils import write_json_atomic

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


def loop_spread(lib) -> dict:
    """Per gait and arm, over the loops: std of the loops' mean elbow bend, std of their bend
    spread (std over the loop), and the correlation of the two (degrees)."""
    import numpy as np

    from convsynth_jax.walktalk.elbow import lc_bend

    out = {}
    for gait, lcs in lib.loops.items():
        for s in ("l", "r"):
            m = np.array([lc_bend(lc, s) for lc in lcs])
            sd = np.array([lc_bend(lc, s, sd=True) for lc in lcs])
            out[f"{gait}_{s}"] = {"loops": len(lcs), "loop_mean_bend_mean_deg": float(m.mean()),
                                  "loop_mean_bend_std_deg": float(m.std(ddof=1)),
                                  "loop_bend_sd_std_deg": float(sd.std(ddof=1)),
                                  "corr_mean_sd": float(np.corrcoef(m, sd)[0, 1])}
    return out


def elbow_variants(sp) -> dict:
    """Stylization variants of the elbow study, {name: (SpliceParams, method)}: from B_D alone (c
    huge, no range-of-motion cut) through the paper's band and the default to our options (soft
    range-of-motion limit, the gait's narrowest band)."""
    rep = dataclasses.replace
    return {
        "B_D alone (c=1e6, no cut)": (rep(sp, c=1e6, respect_joint_limits=False), "stylized"),
        "paper band c=3 (no cut)": (rep(sp, respect_joint_limits=False), "stylized"),
        "c=3 + range-of-motion cut": (sp, "stylized"),
        "+ bounce, bounce_fit=rescale (old)": (rep(sp, bounce_fit="rescale"), "stylized+synced"),
        "+ bounce, bounce_fit=reserve (default)": (sp, "stylized+synced"),
        "soft range of motion (joint_limit_mode=soft), synced": (rep(sp, joint_limit_mode="soft"), "stylized+synced"),
        "band_std=gait_min, synced": (rep(sp, band_std="gait_min"), "stylized+synced"),
        "band_std=gait_min + soft range of motion, synced": (rep(sp, band_std="gait_min", joint_limit_mode="soft"),
                                                              "stylized+synced"),
    }


def elbow_diagnosis(data_dir: Path, every: int = 6, variants: dict | None = None) -> dict:
    """Why the within-gait elbow correlation is low, and what raises it: every walk and run clip as
    a loop, every ``every``-th single-peak gesture, the stylization variants of
    :func:`elbow_variants` through the library's study (elbow.elbow_tracking), with three ways to
    measure the loop's elbow bend (its mean over the loop, the bend of its mean pose B_L, the loop
    over the stroke's own frames). Per gait and variant: the plain per-gesture correlation with each
    loop measure, and the partial one given the loop's bend spread with its slope."""
    import numpy as np

    from convsynth_jax.walktalk.elbow import _per_gesture_corr, elbow_partial_corr, elbow_tracking
    from convsynth_jax.walktalk.library import load_library
    from convsynth_jax.walktalk.params import WalkTalkParams

    p = WalkTalkParams()
    t0 = time.perf_counter()
    lib = load_library(p, data_dir, 10_000, single_peak_only=True)
    variants = elbow_variants(p.splice) if variants is None else variants
    df = elbow_tracking(lib, p, gestures=lib.gestures[::every], variants=variants, loop_measures=True)
    out = []
    for (gait, name), d in df.groupby(["gait", "method"], sort=False):
        rec = {"gait": gait, "variant": name, "loops": len(lib.loops[gait]), "gestures": int(d["gesture"].nunique())}
        for meas, col in (("mean", "loop_bend"), ("pose", "loop_pose_bend"), ("phase", "loop_phase_bend")):
            dd = d.rename(columns={"bend": "elbow_bend_deg", col: "loop_elbow_bend_deg"})
            rec[f"plain_vs_loop_{meas}"] = float(np.mean(_per_gesture_corr(dd)))
        dd = d.rename(columns={"bend": "elbow_bend_deg", "loop_bend": "loop_elbow_bend_deg",
                               "loop_bend_sd": "loop_elbow_bend_sd_deg"})
        pc, sl = elbow_partial_corr(dd)
        rec.update({"partial_given_sd": float(np.mean(pc)), "slope_median": float(np.median(sl))})
        out.append(rec)
    return {"per_gait_variant": out, "loops_spread": loop_spread(lib), "seconds": time.perf_counter() - t0}


def limits_breakdown(data_dir: Path, every: int = 4) -> dict:
    """Where the per-frame joint-limit reading (limit_metrics.limit_violations) fails: every
    ``every``-th single-peak gesture x the evaluation's loops, naive and stylized+synced, per gait:
    the share of t_Pb..t_Re frames failing, split by cause (a gesturing-arm DOF, the gesturing
    hand in the torso, the idle hand in the torso) and by phase (preparation incl. the pad,
    stroke+holds, retraction incl. the pad), beside the loop alone over the same frames; and the
    rate for the stroke frames alone, where the splice writes the gesture only; and the same causes
    per loop (``per_loop``: the splices fail where, and only where, their loop does)."""
    import numpy as np

    from convsynth_jax.kinematics import forward_kinematics_np
    from convsynth_jax.walktalk.evaluate import EvalParams, torso_radius
    from convsynth_jax.walktalk.library import dof_limits, load_library, peak_placed_splices
    from convsynth_jax.walktalk.limit_metrics import LimitCheck, ScoredSpan, limit_violations
    from convsynth_jax.walktalk.params import WalkTalkParams
    from convsynth_jax.walktalk.pipeline import splice_gesture
    from convsynth_jax.walktalk.torso import hand_torso_distance

    p, ep = WalkTalkParams(), EvalParams()
    lib = load_library(p, data_dir, ep.loops_per_gait, single_peak_only=True)
    radius = torso_radius(lib, ep)
    limits = dof_limits(lib, ep.limit_percentiles, ep.limit_tolerance_deg)
    rom = dof_limits(lib, p.splice.joint_limit_percentiles)
    acc: dict = {}
    for gc, gait, lc, T, u, loco, contact in peak_placed_splices(lib, p, lib.gestures[::every]):
        g = gc.gesture
        lpos = forward_kinematics_np(loco)
        for method in ("naive", "stylized+synced"):
            r = splice_gesture(lc, gc, u, T, p.splice, method, loco=loco, contact=contact, limits=rom)
            ph = r.phases
            fr = np.arange(ph.pb, ph.re + 1)
            phase = np.where(fr < ph.sb, "prep", np.where(fr <= ph.se, "stroke", "retraction"))
            for who, m, pos in (("splice", r.motion, forward_kinematics_np(r.motion)), ("loop", loco, lpos)):
                dof, _ = limit_violations(ScoredSpan(m, pos, ph, gc.joints, g.sides), LimitCheck(lib.body, limits, radius))
                inside = hand_torso_distance(pos, lib.body, fr) < radius
                gest = np.array([s in g.sides for s in ("l", "r")])
                tg, ti = inside[:, gest].any(axis=1), inside[:, ~gest].any(axis=1)
                bad = dof | tg | ti
                for key in ((gait, method, who), (gait, method, who, f"{Path(lc.loop.source).stem}[{lc.loop.start}]")):
                    d = acc.setdefault(key, {"frames": 0, "any": 0, "dof": 0, "torso_gesturing": 0, "torso_idle": 0,
                                             **{f"{q}_frames": 0 for q in ("prep", "stroke", "retraction")},
                                             **{f"{q}_any": 0 for q in ("prep", "stroke", "retraction")}})
                    d["frames"] += len(fr)
                    d["any"] += int(bad.sum())
                    d["dof"] += int(dof.sum())
                    d["torso_gesturing"] += int(tg.sum())
                    d["torso_idle"] += int(ti.sum())
                    for q in ("prep", "stroke", "retraction"):
                        d[f"{q}_frames"] += int((phase == q).sum())
                        d[f"{q}_any"] += int((bad & (phase == q)).sum())
    out, per_loop = [], []
    for key, d in acc.items():
        if len(key) == 4:
            per_loop.append({"gait": key[0], "method": key[1], "motion": key[2], "loop": key[3], "frames": d["frames"],
                             **{f"{k}_frac": d[k] / d["frames"] for k in ("any", "dof", "torso_gesturing", "torso_idle")}})
            continue
        gait, method, who = key
        rec = {"gait": gait, "method": method, "motion": who, "frames": d["frames"]}
        for k in ("any", "dof", "torso_gesturing", "torso_idle"):
            rec[f"{k}_frac"] = d[k] / d["frames"]
        for q in ("prep", "stroke", "retraction"):
            rec[f"{q}_share_of_frames"] = d[f"{q}_frames"] / d["frames"]
            rec[f"{q}_frac"] = d[f"{q}_any"] / max(d[f"{q}_frames"], 1)
        out.append(rec)
    return {"per_gait_method": out, "per_loop": per_loop, "gestures": len(lib.gestures[::every]), "torso_radius_cm": radius,
            "limit_clips": {k: lib.source_kind.count(k) for k in dict.fromkeys(lib.source_kind)}}


def gesture_reach(lib, p, variants: dict, base: str, every: int = 4) -> list[dict]:
    """The gesture's reach per gait and variant ({name: (SpliceParams, method)}): the root-relative
    gesturing hand's distance at the stroke peak from the loop's own hand at that frame (cm), every
    ``every``-th gesture x the library's loops (peak-placed splices), and its median ratio to the
    variant ``base``."""
    import numpy as np

    from convsynth_jax.kinematics import forward_kinematics_np
    from convsynth_jax.walktalk.library import dof_limits, peak_placed_splices
    from convsynth_jax.walktalk.pipeline import METHODS, splice_gesture

    rom = dof_limits(lib, p.splice.joint_limit_percentiles)
    hips = lib.body.joints["hips"]
    reach: dict = {}
    for gc, gait, lc, T, u, loco, contact in peak_placed_splices(lib, p, lib.gestures[::every]):
        gst = gc.gesture
        lpos = forward_kinematics_np(loco)
        for name, (sp, method) in variants.items():
            r = splice_gesture(lc, gc, u, T, sp, METHODS[method], loco=loco, contact=contact, limits=rom)
            pos = forward_kinematics_np(r.motion.slice(r.peak, r.peak + 1))[0]
            d = np.mean([np.linalg.norm((pos[lib.body.joints[f"hand_{s}"]] - pos[hips])
                                        - (lpos[r.peak, lib.body.joints[f"hand_{s}"]] - lpos[r.peak, hips]))
                         for s in gst.sides])
            reach.setdefault((gait, name), []).append(float(d))
    rows = []
    for (gait, name), v in reach.items():
        b = np.asarray(reach[gait, base])
        rows.append({"gait": gait, "variant": name, "splices": len(v), "reach_cm_mean": float(np.mean(v)),
                     "reach_cm_median": float(np.median(v)),
                     "base": base, "ratio_to_base_median": float(np.median(np.asarray(v) / np.maximum(b, 1e-6)))})
    return rows


def jerk_coupling(data_dir: Path, couplings=(0.0, 0.1, 0.25, 0.5, 1.0), every: int = 4) -> dict:
    """The splices over 2x the source clips' largest wrist jerk against ``splice.rescale_coupling``
    (ours; 0 = the paper's per-DOF rescale): per coupling, the evaluation (run_evaluation, the
    evaluation's loops, every single-peak gesture) summarized per gait x method (splices over 2x,
    worst ratio and its gesture/loop, peak in contact, shifts, violations, DOFs within +- c sigma),
    and the price, the gesture's reach: the root-relative hand's distance at the stroke peak from
    the loop's own hand at that frame (cm; every ``every``-th gesture x the same loops,
    stylized+synced, naive beside it)."""
    import dataclasses

    from convsynth_jax.walktalk.evaluate import EvalParams, run_evaluation, summarize
    from convsynth_jax.walktalk.library import load_library
    from convsynth_jax.walktalk.params import WalkTalkParams

    p, ep = WalkTalkParams(), EvalParams()
    t0 = time.perf_counter()
    lib = load_library(p, data_dir, ep.loops_per_gait, single_peak_only=True)
    rows = []
    for g in couplings:
        pg = dataclasses.replace(p, splice=dataclasses.replace(p.splice, rescale_coupling=g))
        df = run_evaluation(lib, pg, ep)
        summ = {(r["gait"], r["method"]): r for r in summarize(df)}
        for (gait, method), d in df.groupby(["gait", "method"], sort=False):
            worst = d.loc[d["max_jerk_ratio"].idxmax()]
            r = summ[gait, method]
            rows.append({"coupling": g, "gait": gait, "method": method, "splices": len(d),
                         "over_2x": int((d["max_jerk_ratio"] > 2.0).sum()),
                         "jerk_ratio_max": float(worst["max_jerk_ratio"]),
                         "jerk_ratio_median": float(d["max_jerk_ratio"].median()),
                         "worst": f"{worst['gesture']} on {worst['loop']}",
                         "peak_in_contact_rate": r["peak_in_contact_rate"], "shift_min_s": r["shift_min_s"],
                         "shift_max_s": r["shift_max_s"], "violation_frac_mean": r["violation_frac_mean"],
                         "limit_cell_frac_mean": r["limit_cell_frac_mean"],
                         "dof_within_csigma_rate": r["dof_within_csigma_rate"]})
    variants = {"naive": (p.splice, "naive")}
    variants.update({f"coupling={g}": (dataclasses.replace(p.splice, rescale_coupling=g), "stylized+synced")
                     for g in couplings})
    reach_rows = gesture_reach(lib, p, variants, f"coupling={couplings[0]}", every)
    return {"per_coupling": rows, "reach": reach_rows, "seconds": time.perf_counter() - t0}


COMBINED = {
    "paper defaults": {},
    "gait_min + soft": {"band_std": "gait_min", "joint_limit_mode": "soft"},
    "gait_min + soft + coupling 0.25": {"band_std": "gait_min", "joint_limit_mode": "soft", "rescale_coupling": 0.25},
    "gait_min + soft + coupling 0.5": {"band_std": "gait_min", "joint_limit_mode": "soft", "rescale_coupling": 0.5},
    "gait_min + soft + coupling 1": {"band_std": "gait_min", "joint_limit_mode": "soft", "rescale_coupling": 1.0},
}


def _goal_rows(lib, p, settings: dict, naive_df=None) -> tuple[list[dict], object]:
    """Per setting ({name: SpliceParams overrides}) x gait: every splice goal from one
    run_evaluation of ``lib`` (stylized+synced; naive once, shared, for the "<= naive" parts):
    splices over 2x jerk and the worst, peak in contact, shifts, peaks before the utterance, foot
    slide, DOFs within +- c sigma, joint limits in both readings with the loop alone, naive and
    what the splice introduces over its loop, and the within-gait elbow correlation of these rows
    (plain and partial given the loop's spread, per gesture over its loops)."""
    import pandas as pd

    from convsynth_jax.walktalk.evaluate import EvalParams, run_evaluation, summarize
    from convsynth_jax.walktalk.limit_metrics import limit_readings

    if naive_df is None:
        naive_df = run_evaluation(lib, p, EvalParams(methods=("naive",)))
    rows = []
    for name, kw in settings.items():
        pg = dataclasses.replace(p, splice=dataclasses.replace(p.splice, **kw))
        df = run_evaluation(lib, pg, EvalParams(methods=("stylized+synced",)))
        both = pd.concat([naive_df, df], ignore_index=True)
        summ = {(r["gait"], r["method"]): r for r in summarize(both)}
        lim = {(r["gait"], r["method"]): r for r in limit_readings(list(summ.values()))}
        for gait, d in df.groupby("gait", sort=False):
            worst = d.loc[d["max_jerk_ratio"].idxmax()]
            r, lr = summ[gait, "stylized+synced"], lim[gait, "stylized+synced"]
            rn = summ[gait, "naive"]
            rows.append({
                "setting": name, "overrides": kw, "gait": gait, "splices": len(d),
                "jerk_over_2x": int((d["max_jerk_ratio"] > 2.0).sum()), "jerk_ratio_max": float(worst["max_jerk_ratio"]),
                "jerk_worst": f"{worst['gesture']} on {worst['loop']}",
                "naive_jerk_over_2x": int((naive_df.loc[naive_df["gait"] == gait, "max_jerk_ratio"] > 2.0).sum()),
                "peak_in_contact_rate": r["peak_in_contact_rate"], "shift_min_s": r["shift_min_s"],
                "shift_max_s": r["shift_max_s"], "all_peaks_before_utterance": r["all_peaks_before_utterance"],
                "foot_slide_cm_max": r["foot_slide_cm_max"], "dof_within_csigma_rate": r["dof_within_csigma_rate"],
                "limits_per_frame": lr["per_frame"], "limits_per_cell": lr["per_cell"],
                "met_per_frame": lr["met_per_frame"], "met_per_cell": lr["met_per_cell"],
                "met_per_frame_introduced": lr["met_per_frame_introduced"],
                "elbow_plain": r["elbow_corr_per_gesture_mean"], "elbow_partial": r["elbow_partial_corr_per_gesture_mean"],
                "elbow_plain_naive": rn["elbow_corr_per_gesture_mean"], "elbow_gestures": r["elbow_corr_per_gesture_n"]})
    return rows, naive_df


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
    out["eval"], _ = _goal_rows(lib, p, settings)
    variants = {"naive": (p.splice, "naive")}
    variants.update({name: (dataclasses.replace(p.splice, **kw), "stylized+synced") for name, kw in settings.items()})
    base = next(iter(settings))
    out["reach"] = gesture_reach(lib, p, variants, base)   # the price: the gesture's size at the stroke peak
    out["eval_seconds"] = time.perf_counter() - t0
    lib = load_library(p, data_dir, 10_000, single_peak_only=True)
    lib.gestures = lib.gestures[::every]
    out["sources_all_loops"] = source_readings(lib, scored, radius)
    out["all_loops"], _ = _goal_rows(lib, p, settings)
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


def loop_seams(data_dir: Path) -> dict:
    """What the loop's seam correction (locomotion.seam_correct: the rotation residual between the
    frame after the loop and its first frame spread linearly over the loop) does to the recording,
    per walk and run clip: the largest residual of an arm joint and of any joint (degrees), the
    largest hand shift of the loop from the recorded frames in the torso's frame (cm; the pose's
    change, synthesized.torso_frame; ``hand_shift_world_cm``: root-relative in world axes, which
    also counts the loop's straightened heading), the closest hand to
    the torso axis in the recording's loop frames and in the loop, and the loop's share of frames
    with a hand inside the calibrated torso (evaluate.torso_radius). The bandai2 run clips are
    2-3 cycles long, so their two-cycle windows are not periodic and the correction moves the arms."""
    import numpy as np

    from convsynth_jax.io.bvh import load_bvh
    from convsynth_jax.kinematics import forward_kinematics_np
    from convsynth_jax.rotations import quat_conjugate_np, quat_multiply_np
    from convsynth_jax.walktalk.evaluate import EvalParams, torso_radius
    from convsynth_jax.walktalk.library import load_library
    from convsynth_jax.walktalk.torso import hand_torso_distance
    from convsynth_jax.walktalk.params import WalkTalkParams
    from convsynth_jax.walktalk.conversation_gestures import torso_frame

    p, ep = WalkTalkParams(), EvalParams()
    lib = load_library(p, data_dir, 10_000, max_gestures=1, single_peak_only=True)
    eval_lib = load_library(p, data_dir, ep.loops_per_gait, max_gestures=1, single_peak_only=True)
    chosen = {(lc.loop.source, lc.loop.start) for v in eval_lib.loops.values() for lc in v}
    radius = torso_radius(eval_lib, ep)
    body = lib.body
    arm = list(body.arm_l) + list(body.arm_r)
    hips = body.joints["hips"]
    rows = []
    for gait, lcs in lib.loops.items():
        for lc in lcs:
            lp = lc.loop
            raw = load_bvh(lp.source, fps=p.fps)
            a, n = lp.start, lp.num_frames
            q = np.asarray(raw.rotations, dtype=np.float64)
            r = quat_multiply_np(q[a], quat_conjugate_np(q[a + n]))
            ang = np.degrees(2 * np.arccos(np.clip(np.abs(r[:, 0]), 0, 1)))
            pr, pl = forward_kinematics_np(raw)[a:a + n], forward_kinematics_np(lp.motion)
            world = max(float(np.linalg.norm((pl[:, body.joints[f"hand_{s}"]] - pl[:, hips])
                                             - (pr[:, body.joints[f"hand_{s}"]] - pr[:, hips]), axis=-1).max())
                        for s in ("l", "r"))
            fr, fl = (torso_frame(x, hips, body.joints["neck"], body.joints["upperarm_l"], body.joints["upperarm_r"])
                      for x in (pr, pl))
            shift = max(float(np.linalg.norm(
                np.einsum("fji,fj->fi", fl, pl[:, body.joints[f"hand_{s}"]] - pl[:, hips])
                - np.einsum("fji,fj->fi", fr, pr[:, body.joints[f"hand_{s}"]] - pr[:, hips]), axis=-1).max())
                for s in ("l", "r"))
            dr, dl = hand_torso_distance(pr, body), hand_torso_distance(pl, body)
            rows.append({"gait": gait, "loop": f"{Path(lp.source).stem}[{a}:{a + n}]", "clip_frames": raw.num_frames,
                         "in_eval": (lp.source, lp.start) in chosen, "arm_residual_deg": float(ang[arm].max()),
                         "residual_deg": float(ang.max()), "hand_shift_cm": shift, "hand_shift_world_cm": world,
                         "closest_hand_recorded_cm": float(dr.min()), "closest_hand_loop_cm": float(dl.min()),
                         "hand_in_torso_frac": float(np.mean(np.any(dl < radius, axis=1)))})
    per_gait = []
    for gait in lib.loops:
        d = [r for r in rows if r["gait"] == gait]
        sh = np.array([r["hand_shift_cm"] for r in d])
        per_gait.append({"gait": gait, "loops": len(d), "hand_shift_cm_median": float(np.median(sh)),
                         "hand_shift_cm_max": float(sh.max()), "share_over_5cm": float(np.mean(sh > 5.0)),
                         "loops_with_hand_in_torso": int(sum(r["hand_in_torso_frac"] > 0 for r in d))})
    return {"torso_radius_cm": radius, "per_gait": per_gait, "loops": rows}


def contact_phases(data_dir: Path) -> dict:
    """The contact/flight phases (locomotion.contact_phases) of every walk and run clip's loop:
    per loop the share of frames in contact by each reading and their agreement, and the
    synchronization rule (sync.align_peak, 0.6 s) applied with the stroke peak's nominal frame at
    every frame of the loop in turn: the share of synchronized peaks in contact by each reading,
    beside the share of nominal (unsynchronized) frames in contact.

    The second walking reading (feet apart) contains the primary one by construction, so a third,
    independent reading is reported as a diagnostic (``root_low``, not a label the library uses):
    the hips below their median height over the loop (Sec. 4: the root falls in contact and rises
    in flight; a walker's hips are lowest around double support and highest as the legs pass)."""
    import numpy as np

    from convsynth_jax.errors import WalkTalkError
    from convsynth_jax.io.bvh import load_bvh
    from convsynth_jax.walktalk.body import find_body
    from convsynth_jax.walktalk.locomotion import extract_loop, tile_contact
    from convsynth_jax.walktalk.params import WalkTalkParams
    from convsynth_jax.walktalk.sync import align_peak, shift_frames

    p = WalkTalkParams()
    s_frames = shift_frames(p.splice.max_shift_s, p.fps)
    rows, skipped = [], []
    for pattern in (p.walk_glob, p.jog_glob):
        for f in sorted(data_dir.glob(pattern)):
            m = load_bvh(f, fps=p.fps)
            try:
                lp = extract_loop(m, p.gait, find_body(m.skeleton, str(f)))
            except WalkTalkError as e:
                skipped.append(str(e))
                continue
            n = lp.num_frames
            c, alt = tile_contact(lp, 3 * n), tile_contact(lp, 3 * n, second=True)
            peaks = [k + align_peak(k, c, s_frames, False) for k in range(n + s_frames, 2 * n + s_frames)]
            low = np.tile(lp.root_height <= np.median(lp.root_height), 3)
            rows.append({"loop": f"{f.stem}[{lp.start}:{lp.start + n}]", "gait": lp.gait, "frames": n,
                         "contact_frac": float(lp.contact.mean()), "contact_alt_frac": float(lp.contact_alt.mean()),
                         "agree_frac": float((lp.contact == lp.contact_alt).mean()),
                         "root_low_agree_frac": float((lp.contact == low[:n]).mean()),
                         "synced_in_contact": float(np.mean(c[peaks])),
                         "synced_in_contact_alt": float(np.mean(alt[peaks])),
                         "synced_root_low": float(np.mean(low[peaks]))})
    per_gait = []
    for gait in ("walk", "jog"):
        d = [r for r in rows if r["gait"] == gait]
        if not d:
            continue
        rec = {"gait": gait, "loops": len(d)}
        for k in ("contact_frac", "contact_alt_frac", "agree_frac", "root_low_agree_frac", "synced_in_contact",
                  "synced_in_contact_alt", "synced_root_low"):
            x = np.array([r[k] for r in d])
            rec.update({f"{k}_mean": float(x.mean()), f"{k}_min": float(x.min()), f"{k}_max": float(x.max())})
        per_gait.append(rec)
    return {"per_gait": per_gait, "loops": rows, "skipped": skipped}


# The diagnoses that run alone, instead of the benchmark: flag -> (what it reports, the name of the
# result it writes under experiments/results/).
ALONE = {
    "elbow-diagnosis": ("the elbow-tracking diagnosis", "bench_walktalk_elbow_diagnosis"),
    "limits-breakdown": ("where the per-frame joint-limit reading fails", "bench_walktalk_limits_breakdown"),
    "jerk-coupling": ("the splices over 2x jerk and the gesture's reach against splice.rescale_coupling",
                      "bench_walktalk_jerk"),
    "combined": ("every goal for the candidate settings", "bench_walktalk_combined"),
    "loop-seams": ("what the loops' seam correction does to the recordings", "bench_walktalk_loop_seams"),
    "contact-phases": ("the contact fractions of every loop in both readings", "bench_walktalk_contact_phases"),
}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--skip-ablation", action="store_true")
    ap.add_argument("--skip-elbow", action="store_true")
    ap.add_argument("--quick", action="store_true", help="= --skip-ablation --skip-elbow")
    ap.add_argument("--synthesized-dir", default=None, help="output folder of task=synthesize: also time the demo "
                    "with gestures from that synthesized conversation")
    ap.add_argument("--out", default="bench_walktalk.json", help="file name under experiments/results/")
    for flag, (what, name) in ALONE.items():
        ap.add_argument(f"--{flag}", action="store_true", help=f"only {what} (writes experiments/results/{name}.json)")
    a = ap.parse_args()
    if a.quick:
        a.skip_ablation = a.skip_elbow = True
    data_dir = SHARED / "bandai2" / "bvh"
    if not data_dir.is_dir():
        data_dir = REPO / "tests" / "data" / "walktalk"
    import jax

    result = {"machine": {"platform": platform.platform(), "python": platform.python_version(),
                          "jax": jax.__version__, "devices": [str(d) for d in jax.devices()]},
              "data_dir": str(data_dir), "goals": GOALS}
    def write_only(extra: dict, name: str, rows: str, digits: int, tail: list):
        result.update(extra)
        result["load_average"] = list(os.getloadavg())
        RESULTS.mkdir(parents=True, exist_ok=True)
        write_json_atomic(RESULTS / name, result)
        for r in result[rows]:
            print({k: (round(v, digits) if isinstance(v, float) else v) for k, v in r.items()})
        print(*(result[k] for k in tail))

    if a.contact_phases:
        from _bench import write

        res = contact_phases(data_dir)
        res["load_average"] = list(os.getloadavg())
        return write(ALONE["contact-phases"][1], {"data_dir": str(data_dir), **res})
    if a.limits_breakdown:
        return write_only(limits_breakdown(data_dir), ALONE["limits-breakdown"][1] + ".json", "per_loop", 4,
                          ["limit_clips", "load_average"])
    if a.jerk_coupling:
        jc = jerk_coupling(data_dir)
        write_only(jc, ALONE["jerk-coupling"][1] + ".json", "per_coupling", 4, ["seconds", "load_average"])
        for r in jc["reach"]:
            print({k: (round(v, 3) if isinstance(v, float) else v) for k, v in r.items()})
        return None
    if a.loop_seams:
        res = loop_seams(data_dir)
        write_only(res, ALONE["loop-seams"][1] + ".json", "per_gait", 3, ["torso_radius_cm"])
        for r in res["loops"]:
            if r["in_eval"] or r["hand_in_torso_frac"] > 0:
                print({k: (round(v, 2) if isinstance(v, float) else v) for k, v in r.items()})
        return None
    if a.combined:
        result.update(combined(data_dir))
        result["load_average"] = list(os.getloadavg())
        RESULTS.mkdir(parents=True, exist_ok=True)
        write_json_atomic(RESULTS / f"{ALONE['combined'][1]}.json", result)
        return print_combined(result)
    if a.elbow_diagnosis:
        return write_only(elbow_diagnosis(data_dir), ALONE["elbow-diagnosis"][1] + ".json", "per_gait_variant", 3,
                          ["loops_spread"])
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
    RESULTS.mkdir(parents=True, exist_ok=True)
    result["load_average"] = list(os.getloadavg())
    write_json_atomic(RESULTS / a.out, result)
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
