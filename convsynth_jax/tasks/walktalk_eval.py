"""Task ``walktalk_eval``: every single-peak gesture clip x ``loops_per_gait`` loops per gait x the
methods (naive, stylized, stylized+synced). Writes ``walktalk_eval.csv`` (one row per splice),
``walktalk_eval_summary.csv`` (per gait and method) and the figures ``walktalk_peak_phase.png``,
``walktalk_elbow.png``, ``walktalk_contact_sheet.png``, ``walktalk_gait_phases.png``."""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pandas as pd
from omegaconf import OmegaConf

from ..utils import atomic_path
from ..walktalk.evaluate import EvalParams, run_evaluation, summarize, torso_radius
from ..walktalk.library import dof_limits, load_library, resolve_data_dir
from ..walktalk.limit_metrics import in_sample_violations, limit_readings, source_readings
from ..walktalk.params import params_from_dict

REPO = Path(__file__).resolve().parents[2]


def eval_params(task_cfg) -> EvalParams:
    t = OmegaConf.to_container(task_cfg, resolve=True)
    return EvalParams(loops_per_gait=int(t["loops_per_gait"]), methods=tuple(t["methods"]),
                      torso_radius_cm=None if t.get("torso_radius_cm") is None else float(t["torso_radius_cm"]),
                      torso_radius_quantile=float(t.get("torso_radius_quantile", 0.0)),
                      max_gestures=None if t.get("max_gestures") is None else int(t["max_gestures"]),
                      limit_percentiles=tuple(t["limit_percentiles"]),
                      limit_tolerance_deg=float(t["limit_tolerance_deg"]))


def run(cfg, out_dir: Path) -> dict:
    p = params_from_dict(OmegaConf.to_container(cfg.walktalk, resolve=True))
    ep = eval_params(cfg.task)
    data_dir = resolve_data_dir(p, REPO)
    t0 = time.perf_counter()
    lib = load_library(p, data_dir, ep.loops_per_gait, ep.max_gestures, single_peak_only=True)
    t1 = time.perf_counter()
    df = run_evaluation(lib, p, ep)
    t2 = time.perf_counter()
    summary = summarize(df)
    scored = dof_limits(lib, ep.limit_percentiles, ep.limit_tolerance_deg)
    radius = torso_radius(lib, ep)
    with atomic_path(out_dir / "walktalk_eval.csv") as tmp:
        df.to_csv(tmp, index=False)
    with atomic_path(out_dir / "walktalk_eval_summary.csv") as tmp:
        pd.DataFrame(summary).to_csv(tmp, index=False)
    figures = []
    if cfg.task.get("figures", True) and len(df):
        figures = _figures(df, lib, p, out_dir)
    return {"data_dir": str(data_dir), "gestures": len(lib.gestures),
            "loops": {g: [f"{Path(lc.loop.source).name}[{lc.loop.start}:{lc.loop.start + lc.loop.num_frames}]"
                          for lc in v] for g, v in lib.loops.items()},
            "skipped_clips": lib.skipped, "splices": len(df), "per_gait_method": summary,
            # the joint-limit acceptance in both readings (limit_metrics.limit_readings), with the limit
            # table's clips per kind (walks, runs, gestures, limits-only walk-turns)
            "joint_limit_readings": limit_readings(summary),
            "limit_table_clips": {k: lib.source_kind.count(k) for k in dict.fromkeys(lib.source_kind)},
            # the recorded clips themselves under both parts of the metric (DOFs, hands in the torso)
            "limits_in_sample_violation": in_sample_violations(lib, scored, radius),
            # both readings on the evaluation's own loops and gestures, unmodified (limit_metrics.source_readings)
            "limits_sources": source_readings(lib, scored, radius),
            # the torso check's radius (evaluate.torso_radius): fixed, or calibrated from the recordings
            "torso_radius_cm": radius,
            "torso_radius_source": ("task.torso_radius_cm" if ep.torso_radius_cm is not None else
                                    f"calibrated: quantile {ep.torso_radius_quantile} of the recorded hands' distance "
                                    f"to the hips-neck segment over {len(lib.source_torso)} clips"),
            # share of loop frames in contact (locomotion.contact_phases), per gait: the primary and
            # the second reading, mean over the loops and the range
            "loop_contact_frac": {g: float(np.mean([lc.loop.contact.mean() for lc in v])) for g, v in lib.loops.items() if v},
            "loop_contact": {g: _contact_fracs(v) for g, v in lib.loops.items() if v},
            "load_seconds": t1 - t0, "eval_seconds": t2 - t1, "figures": figures}


def _contact_fracs(lcs) -> dict:
    prim = np.array([lc.loop.contact.mean() for lc in lcs])
    alt = np.array([lc.loop.contact_alt.mean() for lc in lcs])
    agree = np.array([(lc.loop.contact == lc.loop.contact_alt).mean() for lc in lcs])
    return {"loops": len(lcs), "contact_frac_mean": float(prim.mean()), "contact_frac_min": float(prim.min()),
            "contact_frac_max": float(prim.max()), "contact_alt_frac_mean": float(alt.mean()),
            "readings_agree_frac_mean": float(agree.mean()), "readings_agree_frac_min": float(agree.min())}


def _figures(df, lib, p, out_dir: Path) -> list[str]:
    from ..figures import save_figure
    from ..figures.walktalk import (
        elbow_bend_figure,
        gait_phase_panel,
        gait_phases_figure,
        peak_phase_figure,
        splice_contact_sheet_figure,
    )
    from ..walktalk.locomotion import tile_contact, tile_loop
    from ..walktalk.pipeline import splice_gesture

    save_figure(peak_phase_figure(df), out_dir / "walktalk_peak_phase.png")
    save_figure(elbow_bend_figure(df), out_dir / "walktalk_elbow.png")
    # contact sheet: the first jog loop (else walk) with the first gesture, naive vs stylized+synced
    lcs = lib.loops.get("jog") or lib.loops.get("walk")
    lc, gc = lcs[0], lib.gestures[0]
    fg = gc.gesture.motion.num_frames
    T = fg + 2 * (lc.loop.num_frames + 30)
    u = (lc.loop.num_frames + 30 + gc.gesture.phases.peaks[0]) / p.fps + p.splice.lead_s
    loco, contact = tile_loop(lc.loop, T), tile_contact(lc.loop, T)
    rom = dof_limits(lib, p.splice.joint_limit_percentiles)
    res = {m: splice_gesture(lc, gc, u, T, p.splice, m, loco=loco, contact=contact, limits=rom)
           for m in ("naive", "stylized+synced")}
    ph = res["stylized+synced"].phases
    frames = sorted({ph.pb, (ph.pb + ph.sb) // 2, ph.sb, *ph.peaks, ph.se, (ph.rb + ph.re) // 2, ph.re})
    fig = splice_contact_sheet_figure({m: r.motion for m, r in res.items()}, frames,
                                      f"{Path(gc.gesture.name).stem} on {Path(lc.loop.source).stem}")
    save_figure(fig, out_dir / "walktalk_contact_sheet.png")
    # contact/flight phases of the first walk and the first jog loop (locomotion.contact_phases)
    panels = {f"{Path(v[0].loop.source).stem}[{v[0].loop.start}:{v[0].loop.start + v[0].loop.num_frames}]":
              gait_phase_panel(v[0].loop, lib.body) for v in lib.loops.values() if v}
    save_figure(gait_phases_figure(panels, p.gait), out_dir / "walktalk_gait_phases.png")
    return ["walktalk_peak_phase.png", "walktalk_elbow.png", "walktalk_contact_sheet.png", "walktalk_gait_phases.png"]
