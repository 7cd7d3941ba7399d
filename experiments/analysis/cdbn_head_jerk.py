"""Where the constrained DBN's head-scope jerk is lost, stage by stage, with a control for each cause.

On leave-one-out folds of the configured corpus (default: the default synthetic corpus), per window
and character, the head point's average jerk (GENEA, the benchmark's head scope: the global position
of the End Site above the head) and the raw FGD (30-frame windows of the root-relative head point,
every 10th frame, against the ground truth of the same windows) of:

* ``gt_full``: the recording (the benchmark's ground truth);
* ``gt_head_on_mean_body``: the recording's head rotation (Neck * Head) on the still mean-pose body
  that ``system=cdbn`` uses (how much of the jerk is the head rotation itself);
* ``gt_head_kp15_on_mean_body``: the same after the paper's key-point smoothing (15/s, slerp);
* ``<posterior>_mean_{raw,kp15}``: the CDBN's output (sum_i gamma_i mu_i for the smoother, the means
  along the Viterbi path) before and after key-point smoothing, on the mean body;
* ``sampled_path_means_kp15`` / ``sampled_draws_{raw,kp15}``: a state path drawn from the posterior
  (forward filtering, backward sampling) with the state means, or with a draw from each state's
  motion Gaussian per frame (the modelled residual added back);
* ``recorded_body_*`` (``cdbn.synth.body=recording``): on a training recording's body (the
  recording's own head, the ground-truth head smoothed, the CDBN's head, and a still head: the
  control that shows how little of the head scope the head itself decides).

Also the head angles' std (pitch, yaw, roll, degrees) of the recordings, the CDBN's mean and the draws.

    python experiments/analysis/cdbn_head_jerk.py [--folds 0 1] [--override corpus=synthetic_tiny ...]

Writes experiments/results/cdbn_head_jerk.json and .md (with manifests).
"""
import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))

import numpy as np  # noqa: E402
from _bench import loo_setup, write, write_markdown  # noqa: E402

from convsynth_jax.cdbn.features import head_euler_to_quat, head_rotation, speech_features  # noqa: E402
from convsynth_jax.cdbn.synthesize import (  # noqa: E402
    body_excerpt,
    expected_motion,
    head_into_motion,
    head_onto_body,
    keypoint_smooth,
    sample_motion,
    state_posteriors,
)
from convsynth_jax.evaluation.field.fgd import fgd, raw_window_features  # noqa: E402
from convsynth_jax.evaluation.field.kinematic import average_jerk  # noqa: E402
from convsynth_jax.evaluation.field.params import FieldMetricParams  # noqa: E402
from convsynth_jax.evaluation.field.views import motion_view  # noqa: E402
from convsynth_jax.evaluation.loo import fit_fold, session_windows, training_clips, window_input  # noqa: E402
from convsynth_jax.api import cache_dir  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--folds", type=int, nargs="+", default=[0, 1])
    ap.add_argument("--override", nargs="*", default=[])
    args = ap.parse_args()
    t0 = time.perf_counter()
    over = ["system=cdbn", *args.override]
    params, ann, system = loo_setup(over)
    fp, hj, rate = FieldMetricParams(), system.cdbn.features.head_joints, system.cdbn.synth.keypoints_per_second
    names = list(ann)
    rng = np.random.default_rng(params.seed)
    jerk, feats, stds = {}, {}, {}

    def add(key, motion):
        v = motion_view(motion, "head", fp.joints, params.annotate)
        jerk.setdefault(key, []).append(average_jerk(v.global_positions, motion.fps))
        feats.setdefault(key, []).append(raw_window_features(v.relative, fp.fgd.raw_window_frames, fp.fgd.raw_frame_step))

    for fold in args.folds:
        fitted = fit_fold(system, ann, names[fold], "cdbn", cache_dir(params))
        held = ann[names[fold]]
        for w in session_windows(held, params.fps, params.loo.window, params.loo.hop, params.loo.max_windows):
            for role, a in held.items():
                win = window_input(held, role, w, params.fps, 0, with_audio=True)
                n, fps = win.num_frames, win.fps
                gt = a.motion.slice(win.start_frame, win.start_frame + n)
                mdl = fitted[a.character]
                tm, inv = mdl.trained.model, mdl.motion_norm.invert
                mean_body = lambda q: head_into_motion(mdl.template, q, hj)  # noqa: E731
                ang = head_rotation(gt, system.cdbn.features)
                add("gt_full", gt)
                add("gt_head_on_mean_body", mean_body(head_euler_to_quat(ang)))
                add("gt_head_kp15_on_mean_body", mean_body(keypoint_smooth(ang, fps, rate)))
                sz = mdl.speech_norm.apply(speech_features(win.own_audio, system.cdbn.features, n, fps))
                cons = np.asarray(mdl.constraint_map, np.int32)[np.asarray(win.own_frames.label, np.int64)]
                for post in ("smoother", "viterbi"):
                    m = inv(expected_motion(tm, state_posteriors(tm, sz, cons, post)))
                    add(f"{post}_mean_raw", mean_body(head_euler_to_quat(m)))
                    add(f"{post}_mean_kp15", mean_body(keypoint_smooth(m, fps, rate)))
                    if post == "smoother":
                        smooth = m
                mu, draw = sample_motion(tm, sz, cons, rng)
                draw = inv(draw)
                add("sampled_path_means_kp15", mean_body(keypoint_smooth(inv(mu), fps, rate)))
                add("sampled_draws_raw", mean_body(head_euler_to_quat(draw)))
                add("sampled_draws_kp15", mean_body(keypoint_smooth(draw, fps, rate)))
                body = body_excerpt([c.motion for c in training_clips(ann, names[fold], a.character)], n, rng)
                add("recorded_body_own_head", body)
                add("recorded_body_gt_head_kp15", head_onto_body(body, keypoint_smooth(ang, fps, rate), hj))
                add("recorded_body_cdbn_head_kp15", head_onto_body(body, keypoint_smooth(smooth, fps, rate), hj))
                still = head_euler_to_quat(np.repeat(smooth.mean(0, keepdims=True), n, 0))
                add("recorded_body_still_head", head_onto_body(body, still, hj))
                for k, x in (("recordings", ang), ("smoother_mean", smooth), ("sampled_draws", draw)):
                    stds.setdefault(k, []).append(x.std(0))
        print(f"fold {fold}: {time.perf_counter() - t0:.0f} s", flush=True)
    ref = np.concatenate(feats["gt_full"])
    g = float(np.mean(jerk["gt_full"]))
    rows = {k: {"jerk": float(np.mean(v)), "jerk_over_gt": float(np.mean(v)) / g,
                "fgd_raw": fgd(np.concatenate(feats[k]), ref), "windows": len(v)} for k, v in jerk.items()}
    angle_std = {k: np.mean(v, axis=0).round(3).tolist() for k, v in stds.items()}
    result = {"folds": args.folds, "overrides": over, "keypoints_per_second": rate, "head_point": rows,
              "angle_std_pitch_yaw_roll_deg": angle_std, "seconds": time.perf_counter() - t0}
    write("cdbn_head_jerk", result, overrides=over)
    lines = ["| variant | head jerk | / ground truth | raw FGD (head) |", "|---|---|---|---|"]
    lines += [f"| {k} | {r['jerk']:.0f} | {r['jerk_over_gt']:.2f} | {r['fgd_raw']:.1f} |" for k, r in rows.items()]
    lines += ["", "| angles | std pitch, yaw, roll (deg) |", "|---|---|"]
    lines += [f"| {k} | {', '.join(f'{x:.2f}' for x in v)} |" for k, v in angle_std.items()]
    write_markdown("cdbn_head_jerk", lines, overrides=over)


if __name__ == "__main__":
    main()
