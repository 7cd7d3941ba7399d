"""The flow-matching model against random playback (and the motion graph where a naturalness run left
its records) on the same leave-one-out windows, by the measures of ``naturalness.py``.

Per fold: the flow-matching system trained without the held-out session (timed; a cached model is
loaded and its original training time reported), every window of both characters sampled; random
playback (``preset=quality``, condition ``none``) on the same windows. Against the ground truth of
those windows: raw FGD (and random playback's), median per-joint pose std over the recordings' per
character, still frames, beat consistency (and random playback's, and the mismatched ground truth's:
the same role's recording of the same-numbered window of the next session under this window's audio,
as ``task=benchmark``'s control), Table 1's co-occurrence rates with the ground truth's 95% interval,
and the largest frame-to-frame joint step at the joins of the sampling windows against elsewhere.

    nice -n 10 python experiments/analysis/flow_matching_eval.py --folds 0 1 2 [--name flow_matching_eval]
        [--override system.options.train_steps=800 ...] [--graph-work /tmp/naturalness_work --graph-variant quality]

Writes experiments/results/<name>.json and .md with manifests.
"""
import argparse
import pickle
import time
from pathlib import Path

import numpy as np  # noqa: E402
from naturalness import (FP, VARIANTS, body_view, load_cached, measure_lines, noise_floor, rate_lines, run_variant,  # noqa: E402
                         summarize)

from convsynth_jax.config import default_params  # noqa: E402
from convsynth_jax.evaluation.field import beat, window_sets  # noqa: E402
from convsynth_jax.evaluation.field.kinematic import still_frames  # noqa: E402
from convsynth_jax.evaluation.loo import (fit_fold, fold_thresholds, recording_threshold_table,  # noqa: E402
                                          session_windows, window_cooccurrence, window_input)
from convsynth_jax.seeding import derive_seed  # noqa: E402
from convsynth_jax.systems.base import make_system  # noqa: E402
from convsynth_jax.api import annotated_corpus, cache_dir  # noqa: E402
from convsynth_jax.api import write_result as write, write_result_markdown as write_markdown  # noqa: E402

CONDITION = "audio"


def mismatched_bc(ann, fold, w, role, gt, fps, params) -> float:
    """Beat consistency of the same role's recording of window ``w.index`` of the next session under
    this window's audio beats (``task=benchmark``'s mismatched ground truth)."""
    names = list(ann)
    other = names[(fold + 1) % len(names)]
    ws = session_windows(ann[other], fps, params.loo.window, params.loo.hop)
    f0 = int(round(ws[w.index % len(ws)].start * fps))
    n = len(gt["rel"])
    piece = ann[other][role].motion.slice(f0, f0 + n)
    if piece.num_frames < n:
        return float("nan")
    v = body_view(piece, params.annotate)
    return beat.beat_consistency(beat.motion_beats(v.relative[:, gt["upper"]], fps, FP.beat), gt["audio_beats"],
                                 n / fps, FP.beat)


def join_steps(rel, fps_out, model_fps, window_frames, prefix_frames) -> tuple[np.ndarray, np.ndarray]:
    """(body mean-joint steps across the joins of the sampling windows (from the last imposed frame
    to the first generated one), every other step) of one window, cm per frame."""
    from convsynth_jax.flow.joins import window_starts

    step = np.linalg.norm(np.diff(rel, axis=0), axis=-1).mean(axis=1)    # (F - 1,) step t -> t + 1
    ratio = fps_out / model_fps
    n_model = int(np.ceil(len(rel) / ratio))
    at = np.zeros(len(step), bool)
    for s in window_starts(n_model, window_frames, prefix_frames)[1:]:
        j = int(round((s + prefix_frames) * ratio))
        if 1 <= j <= len(step):
            at[j - 1] = True
    return step[at], step[~at]


def fgd_split(recs, gt_store, by_character: bool = True) -> dict:
    """``window_sets.fgd_split`` of the solved windows against the ground truth of the same windows, and
    per character (``<measure>_<character>``) when ``by_character``."""
    ok = [k for k in sorted(gt_store) if recs.get(k, {}).get("ok")]
    if not ok:
        return {}
    out = window_sets.fgd_split([recs[k]["rel"] for k in ok], [gt_store[k]["rel"] for k in ok])
    for c in sorted({gt_store[k]["character"] for k in ok}) if by_character else ():
        part = fgd_split({k: recs[k] for k in ok if gt_store[k]["character"] == c}, gt_store, False)
        out.update({f"{m}_{c}": v for m, v in part.items()})
    return out


def run_flow(folds, ann, table, gt_store, overrides, cache=None, represent=None) -> tuple[dict, dict]:
    """Records of every window of ``folds``: the flow model's samples, or with ``represent`` ("plain" or
    "detail") the ground truth itself through the model's representation (``FlowMatchingSystem.represent``,
    no network; "detail" with the frame-level detail noise): the floor the representation sets."""
    from convsynth_jax.systems.base import WindowResult

    params = default_params(["system=flow_matching", *overrides])
    sysm = make_system(params, params.system)
    names = list(ann)
    fps = params.fps
    cd = Path(cache) if cache else cache_dir(params)
    out, timing = {}, {}    # timing: fold -> its figures
    po = sysm.options
    for fold in folds:
        held_out = names[fold]
        t0 = time.perf_counter()
        fitted = fit_fold(sysm, ann, held_out, CONDITION, cd)
        tf = timing[fold] = {"fit_wall_seconds": time.perf_counter() - t0, "synthesis_seconds": [], "window_seconds": [],
                             "fit_seconds": {c: float(m.model.seconds) for c, m in fitted.items()},
                             "fit_cpu_seconds": {c: float(m.model.cpu_seconds) for c, m in fitted.items()}}
        gt_thr, syn_thr = fold_thresholds(ann, held_out, params.annotate, table)
        held = ann[held_out]
        for w in session_windows(held, fps, params.loo.window, params.loo.hop, params.loo.max_windows):
            for k, (role, a) in enumerate(held.items()):
                key = (fold, w.index, role)
                g = gt_store[key]
                f0 = int(round(w.start * fps))
                seed = derive_seed(params.seed, fold=fold, condition=CONDITION, session=held_out, window_frame=f0,
                                   role_index=k)
                win = window_input(held, role, w, fps, seed, with_audio=True)
                if represent:
                    r0 = time.perf_counter()
                    m = sysm.represent(fitted[a.character], held[role].motion.slice(f0, f0 + win.num_frames), seed,
                                       detail_noise=represent == "detail", chair_index=k)
                    res = WindowResult(True, motion=m, seconds=time.perf_counter() - r0)
                else:
                    res = sysm.synthesize(fitted[a.character], win, CONDITION)
                if not res.success:
                    out[key] = {"ok": False}
                    continue
                tf["synthesis_seconds"].append(res.seconds)
                tf["window_seconds"].append(win.num_frames / fps)
                v = body_view(res.motion, params.annotate)
                n = win.num_frames
                at, other = join_steps(v.relative, fps, po.fps, po.sample_window_frames or po.window_frames,
                                       po.prefix_frames)
                out[key] = {"ok": True, "rel": v.relative.astype(np.float32), "still": still_frames(v.relative, fps),
                            "bc": beat.beat_consistency(beat.motion_beats(v.relative[:, g["upper"]], fps, FP.beat),
                                                        g["audio_beats"], n / fps, FP.beat),
                            "cooc": window_cooccurrence(res.motion, win.own_segments, win.partner_segments,
                                                        syn_thr[a.character], params, "synth"),
                            "join_steps": at, "other_steps": other,
                            "bc_mismatched_gt": mismatched_bc(ann, fold, w, role, g, fps, params)}
        print(f"flow_matching: fold {fold} done ({tf['fit_wall_seconds']:.1f} s fit)", flush=True)
    return out, timing


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--folds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--name", default="flow_matching_eval")
    ap.add_argument("--override", nargs="*", default=[], help="Hydra overrides of the flow-matching run")
    ap.add_argument("--work", default="/tmp/flow_matching_work")
    ap.add_argument("--cache", default=None, help="the model cache (default: the configured loo_cache)")
    ap.add_argument("--graph-work", default=None, help="a naturalness.py --work folder with the motion graph's records")
    ap.add_argument("--graph-variant", default="quality")
    ap.add_argument("--represent", choices=["plain", "detail"], default=None,
                    help="control: the ground truth through the model's representation instead of samples")
    args = ap.parse_args()
    t0 = time.perf_counter()
    params = default_params(["preset=quality"])
    _, ann = annotated_corpus(params)
    table = recording_threshold_table(ann, params.annotate)
    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    tag = "_".join(map(str, args.folds))
    gt_store = load_cached(work, "gt", args.folds) or {}
    rp = load_cached(work, "random_playback", args.folds)
    if rp is None:
        rp = run_variant("random_playback", VARIANTS["random_playback"], args.folds, ann, table, gt_store)
        (work / f"random_playback_{tag}.pkl").write_bytes(pickle.dumps(rp))
        (work / f"gt_{tag}.pkl").write_bytes(pickle.dumps(gt_store))
    t1, c1 = time.perf_counter(), time.process_time()
    flow, timing = load_cached(work, "flow_matching", args.folds), load_cached(work, "flowtiming", args.folds)
    if flow is None or timing is None:   # records of earlier runs whose folds together cover these are reused
        flow, timing = run_flow(args.folds, ann, table, gt_store, args.override, args.cache, args.represent)
        (work / f"flow_matching_{tag}.pkl").write_bytes(pickle.dumps(flow))
        (work / f"flowtiming_{tag}.pkl").write_bytes(pickle.dumps(timing))
        (work / f"gt_{tag}.pkl").write_bytes(pickle.dumps(gt_store))
    flow_seconds, flow_cpu = time.perf_counter() - t1, time.process_time() - c1
    results = {"flow_matching": flow, "random_playback": rp}
    if args.graph_work:
        g = load_cached(Path(args.graph_work), args.graph_variant, args.folds)
        if g is not None:
            results[f"motion_graph_{args.graph_variant}"] = g
    summary = {n: summarize(n, r, gt_store, rp) for n, r in results.items()}
    ok = [k for k in sorted(flow) if flow[k]["ok"]]
    s = summary["flow_matching"]
    s["bc_mismatched_gt_same_windows"] = float(np.nanmean([flow[k]["bc_mismatched_gt"] for k in ok]))
    if all("join_steps" in flow[k] for k in ok):
        at = np.concatenate([flow[k]["join_steps"] for k in ok])
        other = np.concatenate([flow[k]["other_steps"] for k in ok])
        s["join_step_mean"], s["other_step_mean"] = float(at.mean()), float(other.mean())
        s["joins_above_other_p99"] = float((at > np.percentile(other, 99)).mean())
    s["fgd_ratio_to_random_playback"] = s["fgd_raw"] / s["fgd_raw_random_playback_same_windows"]
    fit = [v for t in timing.values() for v in t["fit_seconds"].values()]
    synth = float(sum(np.sum(t["synthesis_seconds"]) for t in timing.values()))
    speech = float(sum(np.sum(t["window_seconds"]) for t in timing.values()))
    fit_cpu = [v for t in timing.values() for v in t.get("fit_cpu_seconds", {}).values()]
    timing_summary = {"flow_run_seconds": flow_seconds, "flow_run_cpu_seconds": flow_cpu,
                      "fit_seconds_per_character_mean": float(np.mean(fit)),
                      "fit_cpu_seconds_per_character_mean": float(np.mean(fit_cpu)) if fit_cpu else float("nan"),
                      "fit_wall_seconds_per_fold": {f: t["fit_wall_seconds"] for f, t in timing.items()},
                      "sampling_seconds_per_60s_speech": synth / speech * 60.0 if speech else float("nan")}
    for n, r in results.items():
        summary[n].update(fgd_split(r, gt_store))
    floor = noise_floor(gt_store, params.fps)
    result = {"folds": args.folds, "overrides": args.override, "represent": args.represent, "summary": summary, "timing": timing_summary,
              "noise_floor": floor, "seconds": time.perf_counter() - t0}
    control = [f"represent={args.represent}"] if args.represent else []
    write(args.name, result, overrides=[f"folds={args.folds}", *args.override, *control])
    write_markdown(args.name, markdown(summary, timing_summary, args.folds),
                   overrides=[f"folds={args.folds}", *args.override, *control])


def markdown(summary, timing, folds) -> list:
    keys = ["windows", "solved", "fgd_raw", "fgd_raw_random_playback_same_windows", "fgd_ratio_to_random_playback",
            "fgd_mean_term", "fgd_cov_term", "total_variance_ratio", "mean_pose_offset_max_cm"]
    chars = sorted({k.rsplit("_", 1)[-1] for s in summary.values() for k in s if k.startswith("pose_std_ratio_")})
    keys += [f"{m}_{c}" for c in chars for m in ("fgd_raw", "fgd_mean_term", "fgd_cov_term", "total_variance_ratio")]
    keys += sorted(k for s in summary.values() for k in s if k.startswith("pose_std_ratio"))
    keys += ["still", "still_gt_same_windows", "beat_consistency", "bc_random_playback_same_windows",
             "bc_mismatched_gt_same_windows", "beat_consistency_gt", "pc_lr_within_gt_interval", "join_step_mean",
             "other_step_mean", "joins_above_other_p99"]
    lines = measure_lines(summary, keys, folds)
    lines += rate_lines(summary, "cooccurrence", "Co-occurrence rates (synthesized, ground truth [95% interval]):")
    lines += ["", "Timing:", "", f"- training per character (mean): {timing['fit_seconds_per_character_mean']:.1f} s wall, "
              f"{timing.get('fit_cpu_seconds_per_character_mean', float('nan')):.1f} s CPU",
              f"- sampling: {timing['sampling_seconds_per_60s_speech']:.2f} s per 60 s of speech",
              f"- the flow-matching part of this run: {timing['flow_run_seconds']:.0f} s wall, "
              f"{timing.get('flow_run_cpu_seconds', float('nan')):.0f} s CPU (this process)"]
    return lines


if __name__ == "__main__":
    main()
