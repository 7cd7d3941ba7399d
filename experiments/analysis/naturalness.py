"""Where the motion graph's naturalness is lost, with a control for each cause, scored against the
ground truth of the same windows.

Every variant runs on the leave-one-out windows of ``--folds`` of the configured corpus (seeds as
``task=loo`` derives them). Variants (``--variants``; ``name=system:condition:override,override``
adds one):

* ``quality``: the motion graph, ``preset=quality``, all constraints; ``paper``: ``preset=paper``;
  ``quality_before``: ``preset=quality`` without its detail options (where the diagnosis started);
  ``quality_no_*``: one option of the preset off;
* the controls: ``before_inertialize`` (blending: inertialization instead of the cross-fade),
  ``before_no_retime`` (holds: no retiming stretches), ``random_playback`` (condition ``none``) and
  ``random_playback_matched`` (transition frequency: excerpts as long as ``--matched-to``'s runs
  between synthetic transitions in the same window);
* candidate fixes, each alone on ``quality_before``: ``before_*`` (``VARIANTS``);
* transition targets and runs: ``quality_no_hub`` (``synth.hub_penalty=0``), ``quality_hub_cap4``,
  ``quality_hub_both``, ``quality_wide``, ``quality_tp10``, ``quality_tp100_wide``;
* ``cuts_of_<variant>``: random content cut exactly where <variant> has its synthetic transitions
  (the cuts' share with the variant's choice of content taken out).

Per window and character: still frames (``evaluation/field/kinematic.still_frames``: mean speed of
the body joints, root-relative, heading-free, fingers out, below 2 units/s) and, for the motion
graph, where each comes from (a retiming stretch: the warp shows path time slower than 0.75x; a
best-effort window; a held source frame; a source frame that is still in its recording); the source
frames visited (entropy of (clip, second) cells, share of the window's most used clip, source seconds
revisited, mean source speed over the training recordings' mean: rest poses); synthetic transitions;
beat consistency with the window's own audio; Table 1's co-occurrence counts (``loo.window_cooccurrence``)
and the same counts read from the source recordings' speeds (:func:`source_cooccurrence`: a blend or
cut is never a gesture); constraints met; the synthetic in-degree of the states transitions enter;
the constrained segments entered in the window (own PC/LR, partner HP).

Per variant, over the windows it solved, against the ground truth of THOSE windows: raw FGD
(``field/fgd``), random playback's raw FGD on the same windows, median per-joint pose std over the
recordings' per character, still share, beat consistency (and random playback's on the same
windows), co-occurrence rates with the ground truth's Wilson 95% interval
(``summaries.cooccurrence_by_condition``), a single-pose Frechet distance (poses every 3rd frame, no
timing), mean run between transitions. Noise floors: the same measures between the ground truth's
odd and even windows.

    python experiments/analysis/naturalness.py --folds 0 1 2 [--variants quality paper ...] [--name naturalness]

Writes experiments/results/<name>.json and .md (with manifests); finished variants are kept in
``--work`` (default /tmp/naturalness_work) and reused by a later run with the same folds, or with
the union of the folds of earlier runs (e.g. ``--folds 0 1 2`` and ``--folds 3 4 5``, then
``--folds 0 1 2 3 4 5``).
"""
import argparse
import pickle
import time
from pathlib import Path

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from convsynth_jax.api import write_result as write, write_result_markdown as write_markdown  # noqa: E402

from convsynth_jax.config import default_params  # noqa: E402
from convsynth_jax.evaluation.field import beat  # noqa: E402
from convsynth_jax.evaluation.field.fgd import fgd  # noqa: E402
from convsynth_jax.evaluation.field.kinematic import STILL_SPEED, mean_joint_speed, still_frames  # noqa: E402
from convsynth_jax.evaluation.field.params import FieldMetricParams  # noqa: E402
from convsynth_jax.evaluation.field.views import motion_view
from convsynth_jax.evaluation.field.window_sets import pose_std_ratio, raw_features, single_poses
from convsynth_jax.evaluation.provenance import blend_mask, source_visits  # noqa: E402
from convsynth_jax.evaluation.loo import (fit_fold, fold_thresholds, recording_threshold_table,  # noqa: E402
                                          session_windows, source_window_cooccurrence, window_cooccurrence,
                                          window_input)
from convsynth_jax.annotate.motion import joint_speeds  # noqa: E402
from convsynth_jax.evaluation.summaries import cooccurrence_by_condition  # noqa: E402
from convsynth_jax.graph.hubs import synthetic_in_degree  # noqa: E402
from convsynth_jax.synth.pipeline import CHAIRS  # noqa: E402
from convsynth_jax.synth.realize import realize  # noqa: E402
from convsynth_jax.seeding import derive_seed  # noqa: E402
from convsynth_jax.synth.retime import warp_times  # noqa: E402
from convsynth_jax.systems.base import SystemParams, WindowResult, make_system  # noqa: E402
from convsynth_jax.systems.random_playback import RandomPlaybackOptions  # noqa: E402
from convsynth_jax.api import annotated_corpus, cache_dir  # noqa: E402

FP = FieldMetricParams()
RP_SPEC = SystemParams(name="random_playback", factory="convsynth_jax.systems.random_playback:RandomPlaybackSystem",
                       conditions={"none": {}}, options={})
# preset=quality before the detail options (the diagnosis and the sweep of fixes ran on it)
BEFORE = ["preset=quality", "synth.retime_detail_frames=0", "synth.blend_detail_frames=0"]
VARIANTS = {   # name -> (system, condition, overrides)
    "quality": ("motion_graph", "all", ["preset=quality"]),
    "paper": ("motion_graph", "all", ["preset=paper"]),
    "quality_before": ("motion_graph", "all", BEFORE),
    # each option of the preset off alone
    "quality_no_retime_detail": ("motion_graph", "all", ["preset=quality", "synth.retime_detail_frames=0"]),
    "quality_no_blend_detail": ("motion_graph", "all", ["preset=quality", "synth.blend_detail_frames=0"]),
    # which constraint kinds cost naturalness: the preset under the ablation conditions
    "quality_none": ("motion_graph", "none", ["preset=quality"]),
    "quality_no_lr": ("motion_graph", "no_lr", ["preset=quality"]),
    "quality_no_hp": ("motion_graph", "no_hp", ["preset=quality"]),
    # the beam's sampling temperature (relative to the median synthetic edge cost; default 0.05):
    # hotter picks transitions less greedily, so paths need not return to the cheapest (nearest) frames
    "quality_temp02": ("motion_graph", "all", ["preset=quality", "search.temperature=0.2"]),
    "quality_temp1": ("motion_graph", "all", ["preset=quality", "search.temperature=1.0"]),
    # controls, on the preset before the detail options
    "before_inertialize": ("motion_graph", "all", [*BEFORE, "synth.blend_method=inertialize"]),
    "before_no_retime": ("motion_graph", "all", [*BEFORE, "search.retime_factor=0"]),
    # candidate fixes, one at a time on the preset before the detail options
    "before_min_speed": ("motion_graph", "all", [*BEFORE, "synth.retime_min_speed=0.9"]),
    "before_retime_detail": ("motion_graph", "all", [*BEFORE, "synth.retime_detail_frames=3"]),
    "before_blend_detail": ("motion_graph", "all", [*BEFORE, "synth.blend_detail_frames=3"]),
    "before_loop_penalty": ("motion_graph", "all", [*BEFORE, "synth.loop_penalty=1"]),
    "before_transition_penalty": ("motion_graph", "all", [*BEFORE, "synth.transition_penalty=1"]),
    "before_retime_detail_inertialize": ("motion_graph", "all", [*BEFORE, "synth.retime_detail_frames=3",
                                                                 "synth.blend_method=inertialize"]),
    "random_playback": ("random_playback", "none", ["preset=quality"]),
    "random_playback_matched": ("random_playback", "none", ["preset=quality"]),
    # the same excerpts joined by inertialization instead of the cross-fade: the blend's share
    "random_playback_matched_inertialize": ("random_playback", "none", ["preset=quality",
                                                                        "synth.blend_method=inertialize"]),
    "before_blend12": ("motion_graph", "all", [*BEFORE, "synth.blend_frames=12"]),
    # transition targets that represent the recordings: a synthetic edge into a hub (a state many
    # synthetic edges enter) costs more (synth.hub_penalty, graph/hubs.py), alone and with a cost per
    # transition (synth.transition_penalty: fewer, longer runs)
    # (preset=quality sets hub_penalty 5, hub_cap 16)
    "quality_no_hub": ("motion_graph", "all", ["preset=quality", "synth.hub_penalty=0"]),
    "quality_hub_cap4": ("motion_graph", "all", ["preset=quality", "synth.hub_cap=4"]),
    "quality_hub_both": ("motion_graph", "all", ["preset=quality", "synth.hub_ends=both"]),
    "quality_tp10": ("motion_graph", "all", ["preset=quality", "synth.transition_penalty=10"]),
    # the wide retry's beam and candidate budget as the first attempt (cheaper paths to less-visited targets)
    "quality_wide": ("motion_graph", "all", ["preset=quality", "search.beam_size=2048", "search.max_candidates=16384"]),
    # fewer, longer runs: a cost per transition with the wide beam (the frontier's other end)
    "quality_tp100_wide": ("motion_graph", "all", ["preset=quality", "synth.transition_penalty=100",
                                                   "search.beam_size=2048", "search.max_candidates=16384"]),
}
# controls made from another variant's records: "cuts_of_<variant>" plays random content (random clips
# and positions, as random playback) cut exactly where <variant> has its synthetic transitions, with
# the same blend: what the cuts alone cost, with the variant's choice of content taken out
CUTS_OF = "cuts_of_"
SLOW = 0.75          # a retiming stretch: path time shown slower than this
PC_LR = ("PC-LH/RH", "LR-Nod")   # the rates the acceptance checks


def body_view(motion, annotate):
    return motion_view(motion, "body", FP.joints, annotate)


def held_speeds(session, role, motion, params, _cache={}):
    """joint_speeds of a held-out recording (cached per recording)."""
    if (session, role) not in _cache:
        _cache[(session, role)] = joint_speeds(motion, params.annotate)
    return _cache[(session, role)]


def source_cooccurrence(clips, frames, speeds: dict, win, thresholds, params, prefix) -> dict:
    """Table 1's co-occurrence counts of one window read from the source recordings
    (``loo.source_window_cooccurrence``: a blend or a cut is never a gesture)."""
    return source_window_cooccurrence(clips, frames, speeds, win.own_segments, win.partner_segments, win.fps,
                                      thresholds, params, prefix)


def constrained_entries(win) -> int:
    """Input segments the motion graph must enter inside the window (own PC and LR, partner HP starting
    in it): with one recorded run per clause, each costs a synthetic transition, so their number per
    window bounds what a search without multi-clause runs can reach."""
    n = 0
    for segs, kinds in ((win.own_segments, ("PC", "LR")), (win.partner_segments, ("HP",))):
        if segs is None or not len(segs):
            continue
        st = np.asarray(segs["start"], float)
        n += int(np.sum(np.isin(segs["kind"], kinds) & (st > 0) & (st < win.num_frames / win.fps)))
    return n


def target_in_degree(graph, clips, frames, cuts, deg) -> list:
    """Synthetic in-degree of the states each synthetic transition of a path enters (by the source clip
    and frame at the cut)."""
    index = {(graph.clip_names[c], int(f)): s for s, (c, f) in enumerate(zip(graph.clip, graph.frame))}
    out = []
    for t in cuts:
        s = index.get((clips[t], int(frames[t])))
        if s is not None:
            out.append(int(deg[s]))
    return out


def random_at_cuts(model, win, cuts, params) -> WindowResult:
    """Random content (random training clip and start per excerpt, as random playback) cut exactly at
    ``cuts`` (output frames), realized with the preset's blend."""
    rng = np.random.default_rng(win.seed)
    names = sorted(model.motions)
    n = win.num_frames
    bounds = [0, *cuts, n]
    clips, frames = [], []
    for a, b in zip(bounds[:-1], bounds[1:]):
        length = b - a
        for _ in range(100):
            name = names[rng.integers(len(names))]
            if model.motions[name].num_frames >= length:
                break
        avail = model.motions[name].num_frames
        start = int(rng.integers(0, max(1, avail - length + 1)))
        fr = np.minimum(np.arange(start, start + length), avail - 1)
        clips += [name] * length
        frames += fr.tolist()
    chair, yaw = CHAIRS.get(win.chair_index, CHAIRS[0])
    blend = int(params.synth.blend_frames)
    motion = realize(clips, frames, model.motions, cuts, chair=chair, chair_yaw_deg=yaw, blend_frames=blend,
                     blend_method=str(params.synth.blend_method))
    return WindowResult(True, motion, 0.0, 0, 0, None, clips, np.asarray(frames),
                        {"num_synthetic_transitions": len(cuts)}, cuts, blend)


def run_variant(name, spec, folds, ann, table, gt_store, matched_from=None, cuts_from=None) -> dict:
    """key (fold, window, role) -> record of one variant."""
    system_name, condition, over = spec
    params = default_params(list(over))
    names = list(ann)
    fps = params.fps
    if system_name == "random_playback":   # its options from the overrides when they name the system
        sysm = make_system(params, params.system if params.system.name == "random_playback" else RP_SPEC)
    else:
        sysm = make_system(params, params.system)
    cd = cache_dir(params)
    speeds_of: dict = {}     # character -> clip -> joint_speeds of the training recording
    in_deg: dict = {}        # character -> (graph, synthetic in-degree per state)
    src_speed: dict = {}
    mean_speed: dict = {}
    out = {}
    for fold in folds:
        held_out = names[fold]
        fitted = fit_fold(sysm, ann, held_out, condition, cd)
        gt_thr, syn_thr = fold_thresholds(ann, held_out, params.annotate, table)
        held = ann[held_out]
        speeds_of = {char: {} for char in fitted}
        in_deg = {char: synthetic_in_degree(m.graph) for char, m in fitted.items() if hasattr(m, "graph")}
        for char, model in fitted.items():   # the training recordings' body speed: rest poses
            for c, m in model.motions.items():
                if (char, c) not in src_speed:
                    src_speed[(char, c)] = mean_joint_speed(body_view(m, params.annotate).relative, m.fps)
            mean_speed[char] = float(np.mean(np.concatenate([src_speed[(char, c)] for c in model.motions])))
        for w in session_windows(held, fps, params.loo.window, params.loo.hop, params.loo.max_windows):
            for k, (role, a) in enumerate(held.items()):
                key = (fold, w.index, role)
                f0 = int(round(w.start * fps))
                seed = derive_seed(params.seed, fold=fold, condition=condition, session=held_out, window_frame=f0,
                                   role_index=k)
                win = window_input(held, role, w, fps, seed, with_audio=True)
                n = win.num_frames
                if key not in gt_store:
                    gt = a.motion.slice(f0, f0 + n)
                    v = body_view(gt, params.annotate)
                    ab = beat.audio_beats(win.own_audio, FP.beat)
                    gt_store[key] = {
                        "character": a.character, "session": held_out, "rel": v.relative.astype(np.float32),
                        "still": still_frames(v.relative, fps), "audio_beats": ab,
                        "bc": beat.beat_consistency(beat.motion_beats(v.relative[:, list(v.upper)], fps, FP.beat),
                                                    ab, n / fps, FP.beat),
                        "cooc": window_cooccurrence(gt, win.own_segments, win.partner_segments, gt_thr[role],
                                                    params, "gt"),
                        "upper": list(v.upper)}
                if "entries" not in gt_store[key]:
                    gt_store[key]["entries"] = constrained_entries(win)
                if "cooc_src" not in gt_store[key]:   # the same count read from the recording's own speeds
                    gt_store[key]["cooc_src"] = source_cooccurrence(
                        [f"{held_out}:{role}"] * n, np.arange(f0, f0 + n), {f"{held_out}:{role}": held_speeds(
                            held_out, role, a.motion, params)}, win, gt_thr[role], params, "gt")
                g = gt_store[key]
                if cuts_from is not None:
                    ref = cuts_from.get(key)
                    if ref is None or not ref["ok"]:
                        out[key] = {"ok": False}
                        continue
                    res = random_at_cuts(fitted[a.character], win, list(ref["cuts"]), params)
                elif matched_from is not None:
                    ref = matched_from.get(key)
                    if ref is None or not ref["ok"]:
                        out[key] = {"ok": False}
                        continue
                    run = n / fps / (ref["transitions"] + 1)
                    sysm.options = RandomPlaybackOptions(min_excerpt_seconds=run, max_excerpt_seconds=run)
                    res = sysm.synthesize(fitted[a.character], win, condition)
                else:
                    res = sysm.synthesize(fitted[a.character], win, condition)
                if matched_from is not None and res.success:   # excerpts of round(run * fps) frames each
                    want = -(-n // max(1, int(round(run * fps)))) - 1
                    if len(res.synthetic_at or []) != want:
                        raise RuntimeError(f"{name} {key}: {len(res.synthetic_at or [])} transitions where excerpts of "
                                           f"{run:.2f} s make {want}: the excerpt lengths did not apply")
                if not res.success:
                    out[key] = {"ok": False}
                    continue
                v = body_view(res.motion, params.annotate)
                still = still_frames(v.relative, fps)
                clips, frames = list(res.source_clip), np.asarray(res.source_frame)
                sp = np.array([src_speed[(a.character, c)][f] for c, f in zip(clips, frames)])
                cuts = [int(t) for t in (res.synthetic_at or [])]
                for c in set(clips) - set(speeds_of[a.character]):
                    speeds_of[a.character][c] = joint_speeds(fitted[a.character].motions[c], params.annotate)
                rec = {"ok": True, "rel": v.relative.astype(np.float32), "still": still,
                       "transitions": len(cuts), "cuts": cuts, "num_frames": n, "fps": fps,
                       "met": int(res.constraints_met), "total": int(res.constraints_total),
                       "cooc_src": source_cooccurrence(clips, frames, speeds_of[a.character], win,
                                                       syn_thr[a.character], params, "synth"),
                       "bc": beat.beat_consistency(beat.motion_beats(v.relative[:, g["upper"]], fps, FP.beat),
                                                   g["audio_beats"], n / fps, FP.beat),
                       "cooc": window_cooccurrence(res.motion, win.own_segments, win.partner_segments,
                                                   syn_thr[a.character], params, "synth"),
                       **source_visits(clips, frames, fps, sp < STILL_SPEED, sp / mean_speed[a.character])}
                d = res.diagnostics
                if system_name == "motion_graph":   # masks of where still frames may come from
                    rec["target_in_degree"] = target_in_degree(fitted[a.character].graph, clips, frames, cuts,
                                                               in_deg[a.character])
                    rec["mean_in_degree"] = float(in_deg[a.character].mean())
                    warp = d.get("warp")
                    rec.update({"best_effort": bool(d.get("best_effort")),
                                "slow": np.gradient(warp_times(n, *warp)) < SLOW if warp is not None else np.zeros(n, bool),
                                "held_src": np.r_[False, frames[1:] == frames[:-1]], "src_still": sp < STILL_SPEED,
                                "blend": blend_mask(n, res.synthetic_at or [], int(res.blend_frames or 0))})
                out[key] = rec
        print(f"{name}: fold {fold} done", flush=True)
    return out


def cooc_rates(keys, recs, gt_store, label, field="cooc") -> pd.DataFrame:
    rows = []
    for key in keys:
        g = gt_store[key]
        r = recs.get(key, {"ok": False})
        row = {"condition": label, "character": g["character"], "success": bool(r["ok"]), **g[field]}
        if r["ok"]:
            row.update(r[field])
        rows.append(row)
    return cooccurrence_by_condition(pd.DataFrame(rows))


def summarize(name, recs, gt_store, rp) -> dict:
    keys = sorted(k for k in gt_store if k in recs)
    ok = [k for k in keys if recs[k]["ok"]]
    chars = sorted({gt_store[k]["character"] for k in ok})
    out = {"windows": len(keys), "solved": len(ok)}
    if not ok:
        return out
    gt_feat = raw_features([gt_store[k]["rel"] for k in ok])
    out["fgd_raw"] = fgd(raw_features([recs[k]["rel"] for k in ok]), gt_feat)
    out["pose_frechet"] = fgd(single_poses([recs[k]["rel"] for k in ok]), single_poses([gt_store[k]["rel"] for k in ok]))
    tot = sum(recs[k].get("total", 0) for k in ok)
    if tot:
        out["constraints_met"] = sum(recs[k]["met"] for k in ok) / tot
    if all("num_frames" in recs[k] for k in ok):
        out["mean_run_seconds"] = (sum(recs[k]["num_frames"] / recs[k]["fps"] for k in ok)
                                   / sum(recs[k]["transitions"] + 1 for k in ok))
    if all("entries" in gt_store[k] for k in ok):
        out["constrained_entries"] = float(np.mean([gt_store[k]["entries"] for k in ok]))
    deg = [d for k in ok for d in recs[k].get("target_in_degree", [])]
    if deg:
        out["target_in_degree"] = float(np.mean(deg))
        out["state_in_degree"] = float(np.mean([recs[k]["mean_in_degree"] for k in ok]))
    rp_ok = [k for k in ok if rp.get(k, {}).get("ok")]
    if rp_ok:
        out["fgd_raw_random_playback_same_windows"] = fgd(raw_features([rp[k]["rel"] for k in rp_ok]),
                                                          raw_features([gt_store[k]["rel"] for k in rp_ok]))
        out["bc_random_playback_same_windows"] = float(np.nanmean([rp[k]["bc"] for k in rp_ok]))
    out["fgd_raw_gt_same_windows_vs_all"] = fgd(gt_feat, raw_features([gt_store[k]["rel"] for k in keys]))
    for c in chars:
        kc = [k for k in ok if gt_store[k]["character"] == c]
        out[f"pose_std_ratio_{c}"] = pose_std_ratio([recs[k]["rel"] for k in kc], [gt_store[k]["rel"] for k in kc])
    out["still"] = float(np.mean(np.concatenate([recs[k]["still"] for k in ok])))
    mg = [k for k in ok if "slow" in recs[k]]
    if mg:
        def share(mask):
            return float(np.mean(np.concatenate([recs[k]["still"] & mask(recs[k]) for k in mg])))
        out["best_effort"] = float(np.mean([recs[k]["best_effort"] for k in mg]))
        out["retime_slow_share"] = float(np.mean(np.concatenate([recs[k]["slow"] for k in mg])))
        out["still_in_retime_stretch"] = share(lambda r: r["slow"])
        out["still_in_best_effort"] = share(lambda r: np.full(len(r["still"]), r["best_effort"]))
        out["still_on_held_source"] = share(lambda r: r["held_src"])
        out["still_on_still_source"] = share(lambda r: r["src_still"])
        out["still_in_blend"] = share(lambda r: r["blend"])
        out["still_other"] = share(lambda r: ~(r["slow"] | r["held_src"] | r["src_still"] | r["blend"] | r["best_effort"]))
    out["still_gt_same_windows"] = float(np.mean(np.concatenate([gt_store[k]["still"] for k in ok])))
    out["beat_consistency"] = float(np.nanmean([recs[k]["bc"] for k in ok]))
    out["beat_consistency_gt"] = float(np.nanmean([gt_store[k]["bc"] for k in ok]))
    for m in ("transitions", "entropy_bits", "source_still_share", "top_clip_share", "revisited_seconds",
              "source_speed_ratio"):
        vals = [float(recs[k][m]) for k in ok if m in recs[k]]
        if vals:
            out[m] = float(np.mean(vals))
    co = cooc_rates(keys, recs, gt_store, name)
    rates = {}
    for _, r in co.iterrows():
        within = bool(r["gt_ci_low"] <= r["synth_rate"] <= r["gt_ci_high"])
        rates[f"{r['character']}:{r['hypothesis']}"] = {
            "synth_rate": float(r["synth_rate"]), "synth_total": int(r["synth_total"]), "gt_rate": float(r["gt_rate"]),
            "gt_ci": [float(r["gt_ci_low"]), float(r["gt_ci_high"])], "within_gt_interval": within}
    out["cooccurrence"] = rates
    out["pc_lr_within_gt_interval"] = all(v["within_gt_interval"] for k, v in rates.items()
                                          if k.split(":", 1)[1] in PC_LR)
    if all("cooc_src" in recs[k] for k in ok) and all("cooc_src" in gt_store[k] for k in keys):
        rates = {}
        for _, r in cooc_rates(keys, recs, gt_store, name, "cooc_src").iterrows():
            within = bool(r["gt_ci_low"] <= r["synth_rate"] <= r["gt_ci_high"])
            rates[f"{r['character']}:{r['hypothesis']}"] = {
                "synth_rate": float(r["synth_rate"]), "synth_total": int(r["synth_total"]),
                "gt_rate": float(r["gt_rate"]), "gt_ci": [float(r["gt_ci_low"]), float(r["gt_ci_high"])],
                "within_gt_interval": within}
        out["cooccurrence_source"] = rates
    return out


def noise_floor(gt_store, fps: float) -> dict:
    """The same measures between the ground truth's odd and even windows (a metric's noise floor)."""
    keys = sorted(gt_store)
    odd = [k for k in keys if k[1] % 2]
    even = [k for k in keys if not k[1] % 2]
    out = {"fgd_raw_odd_vs_even": fgd(raw_features([gt_store[k]["rel"] for k in odd]),
                                      raw_features([gt_store[k]["rel"] for k in even]))}
    for c in sorted({gt_store[k]["character"] for k in keys}):
        ro = [gt_store[k]["rel"] for k in odd if gt_store[k]["character"] == c]
        re_ = [gt_store[k]["rel"] for k in even if gt_store[k]["character"] == c]
        out[f"pose_std_ratio_{c}_odd_over_even"] = pose_std_ratio(ro, re_)
    # mismatched ground truth: each window's recorded motion against the audio beats of the same
    # role's next window of its fold (the first window for the last): beat consistency by chance
    by = {k: gt_store[k] for k in keys}
    mism = []
    for k in keys:
        nxt = (k[0], k[1] + 1, k[2]) if (k[0], k[1] + 1, k[2]) in by else (k[0], min(w for f, w, r in keys
                                                                                   if f == k[0] and r == k[2]), k[2])
        if nxt == k:
            continue
        g, o = by[k], by[nxt]
        n = len(g["rel"])
        mism.append(beat.beat_consistency(beat.motion_beats(g["rel"][:, g["upper"]], fps, FP.beat), o["audio_beats"],
                                          n / fps, FP.beat))
    out["beat_consistency_gt_mismatched"] = float(np.nanmean(mism)) if mism else float("nan")
    st = [float(np.mean(np.concatenate([gt_store[k]["still"] for k in ks]))) for ks in (odd, even)]
    bc = [float(np.nanmean([gt_store[k]["bc"] for k in ks])) for ks in (odd, even)]
    out.update({"still_odd": st[0], "still_even": st[1], "beat_consistency_odd": bc[0], "beat_consistency_even": bc[1],
                "still_all": float(np.mean(np.concatenate([gt_store[k]["still"] for k in keys]))),
                "beat_consistency_all": float(np.nanmean([gt_store[k]["bc"] for k in keys]))})
    return out


def load_cached(work: Path, prefix: str, folds) -> dict | None:
    """The records of ``prefix`` (a variant, or ``gt``) for ``folds`` from ``work``: the file of exactly
    these folds, else the union of files of other runs whose folds all lie in ``folds`` when together
    they cover every one of them; None when they do not."""
    tag = "_".join(map(str, folds))
    exact = work / f"{prefix}_{tag}.pkl"
    if exact.is_file():
        return pickle.loads(exact.read_bytes())
    merged, covered = {}, set()
    for path in sorted(work.glob(f"{prefix}_*.pkl")):
        rest = path.stem[len(prefix) + 1:]
        if not all(x.isdigit() for x in rest.split("_")):
            continue      # another variant whose name starts with this one's
        fs = {int(x) for x in rest.split("_")}
        if fs <= set(folds) and not fs & covered:
            merged.update(pickle.loads(path.read_bytes()))
            covered |= fs
    return merged if covered == set(folds) else None


def parse_variant(text):
    name, rest = text.split("=", 1)
    system, condition, over = (rest.split(":", 2) + [""])[:3]
    return name, (system, condition, [o for o in over.split(",") if o])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--folds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--variants", nargs="+", default=list(VARIANTS))
    ap.add_argument("--define", nargs="*", default=[], help="name=system:condition:override,override")
    ap.add_argument("--name", default="naturalness")
    ap.add_argument("--matched-to", default="quality_before",
                    help="the variant whose runs between synthetic transitions random_playback_matched copies")
    ap.add_argument("--work", default="/tmp/naturalness_work")
    args = ap.parse_args()
    t0 = time.perf_counter()
    specs = dict(VARIANTS)
    specs.update(dict(parse_variant(d) for d in args.define))
    params = default_params(["preset=quality"])
    _, ann = annotated_corpus(params)
    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    tag = "_".join(map(str, args.folds))
    gt_path = work / f"gt_{tag}.pkl"
    gt_store = load_cached(work, "gt", args.folds) or {}
    table = recording_threshold_table(ann, params.annotate)
    results = {}
    order = list(args.variants)
    ref = args.matched_to
    for m in [v for v in order if v.startswith("random_playback_matched")]:
        if ref in order:   # its excerpts follow that variant's runs
            order.remove(m)
            order.insert(order.index(ref) + 1, m)
    for c in [v for v in order if v.startswith(CUTS_OF)]:
        specs[c] = ("random_playback", "none", ["preset=quality"])
        src = c[len(CUTS_OF):]
        if src in order and order.index(src) > order.index(c):   # after the variant whose cuts it copies
            order.remove(c)
            order.insert(order.index(src) + 1, c)
    for name in order:
        path = work / f"{name}_{tag}.pkl"
        cached = load_cached(work, name, args.folds)
        if cached is not None:
            results[name] = cached
            continue
        is_matched = name.startswith("random_playback_matched")
        matched = results.get(ref) if is_matched else None
        if is_matched and matched is None:
            raise SystemExit(f"random_playback_matched needs the {ref} variant (--matched-to)")
        cuts_from = None
        if name.startswith(CUTS_OF):
            cuts_from = results.get(name[len(CUTS_OF):]) or load_cached(work, name[len(CUTS_OF):], args.folds)
            if cuts_from is None:
                raise SystemExit(f"{name} needs the records of {name[len(CUTS_OF):]} (run that variant first)")
        results[name] = run_variant(name, specs[name], args.folds, ann, table, gt_store, matched, cuts_from)
        path.write_bytes(pickle.dumps(results[name]))
        gt_path.write_bytes(pickle.dumps(gt_store))
    rp = results.get("random_playback", {})
    summary = {name: summarize(name, recs, gt_store, rp) for name, recs in results.items()}
    floor = noise_floor(gt_store, params.fps)
    result = {"folds": args.folds, "variants": {n: {"system": specs[n][0], "condition": specs[n][1],
                                                    "overrides": specs[n][2]} for n in results},
              "still_speed": STILL_SPEED, "summary": summary, "noise_floor": floor,
              "seconds": time.perf_counter() - t0}
    write(args.name, result, overrides=[f"folds={args.folds}"])
    write_markdown(args.name, markdown(summary, floor, args.folds), overrides=[f"folds={args.folds}"])


def _fmt(x) -> str:
    if x is None:
        return "-"
    if isinstance(x, bool):
        return "yes" if x else "no"
    return f"{x:.3g}"


def measure_lines(summary, keys, folds) -> list:
    """Markdown: the folds, then a table of ``keys`` (each once, in order) by variant."""
    names, keys = list(summary), list(dict.fromkeys(keys))
    lines = [f"folds {folds}", "", "| measure | " + " | ".join(names) + " |", "|---|" + "---|" * len(names)]
    return lines + [f"| {k} | " + " | ".join(_fmt(summary[n].get(k)) for n in names) + " |" for k in keys]


def rate_lines(summary, field: str, title: str) -> list:
    """Markdown: the co-occurrence rates of ``field`` by variant (synthesized, ground truth and its 95%
    interval, 'out' outside it); nothing when no variant has them."""
    names = list(summary)
    rates = sorted({r for s in summary.values() for r in s.get(field, {})})
    if not rates:
        return []
    lines = ["", title, "", "| rate | " + " | ".join(names) + " |", "|---|" + "---|" * len(names)]
    for r in rates:
        cells = []
        for n in names:
            v = summary[n].get(field, {}).get(r)
            cells.append("-" if v is None else f"{v['synth_rate']:.2f} ({v['gt_rate']:.2f} [{v['gt_ci'][0]:.2f}, "
                         f"{v['gt_ci'][1]:.2f}]){'' if v['within_gt_interval'] else ' out'}")
        lines.append(f"| {r} | " + " | ".join(cells) + " |")
    return lines


def markdown(summary, floor, folds) -> list:
    keys = ["windows", "solved", "constraints_met", "fgd_raw", "fgd_raw_random_playback_same_windows",
            "fgd_raw_gt_same_windows_vs_all", "pose_frechet"]
    keys += sorted(k for s in summary.values() for k in s if k.startswith("pose_std_ratio"))
    keys += ["still", "still_gt_same_windows", "beat_consistency", "bc_random_playback_same_windows",
             "beat_consistency_gt", "pc_lr_within_gt_interval", "transitions", "constrained_entries", "mean_run_seconds", "target_in_degree",
             "state_in_degree", "entropy_bits", "top_clip_share",
             "revisited_seconds", "source_speed_ratio", "source_still_share", "best_effort", "retime_slow_share",
             "still_in_retime_stretch", "still_in_best_effort", "still_on_held_source", "still_on_still_source",
             "still_in_blend", "still_other"]
    lines = measure_lines(summary, keys, folds)
    lines += rate_lines(summary, "cooccurrence", "Co-occurrence rates (synthesized, ground truth [95% interval]):")
    lines += rate_lines(summary, "cooccurrence_source", "Co-occurrence rates read from the source recordings' speeds "
                        "(a blend or cut is never a gesture; synthesized, ground truth [95% interval]):")
    lines += ["", "Noise floor (ground truth, odd vs even windows):", "", "| measure | value |", "|---|---|"]
    lines += [f"| {k} | {v:.3g} |" for k, v in floor.items()]
    return lines


if __name__ == "__main__":
    main()
