"""Where the constrained DBN's head-rotation energy is lost, in the head rotation itself (not the head
point, which also carries the body: see cdbn_head_jerk.py), stage by stage, with its spectrum.

On leave-one-out folds of the configured corpus (default: the default synthetic corpus), per window
and character, the head angles (pitch, yaw, roll in degrees, the composed Neck * Head rotation the
model is trained on) of the recording and of the CDBN (smoother means and Viterbi means), each:

* ``raw``: every frame at the corpus's 30 fps;
* ``keys``: only the key frames (15/s), as a 15 fps sequence: what the selection keeps;
* ``kp15``: the paper's key points joined by quaternion slerp (``cdbn.synth.keypoints_per_second``);
* ``kp15_euler``: the same key points joined linearly in Euler angles (does the rotation
  representation matter?);
* ``x120_raw`` / ``x120_kp15``: the sequence upsampled to the paper's 120 fps (cubic spline) before
  the key points (15/s = every 8th frame at 120 fps; does the frame rate matter?);
* ``draws_kp15``: a state path drawn from the posterior with a draw from each state's motion
  Gaussian per frame, then key points (drawing from the emission instead of the means);
* ``random_playback``: the head angles of an excerpt of one of the character's training recordings;
* ``spectral``: the smoother means after the key points plus the spectral residual
  (``cdbn.synth.residual=spectral``, ours; fitted on the training clips of the fold).

For each: the mean angular jerk (norm over the three angles, deg/s^3, GENEA's average jerk), its ratio
to the recording's raw jerk, the angles' SD, and the share of the jerk power (PSD x (2 pi f)^6) and of
the variance in the bands 0-1, 1-3, 3-7.5 and 7.5-15 Hz, and the raw FGD of the head angles (30-frame
windows every 10th frame, against the recording's same windows; the head-rotation view, which the
head point on a moving body hardly shows) and its ratio to random playback's.

    python experiments/analysis/cdbn_energy.py [--folds 0] [--conditions cdbn jdbn] [--override ...]

Writes experiments/results/cdbn_energy.json and .md (with manifests).
"""
import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))

import numpy as np  # noqa: E402
from _bench import loo_setup, write, write_markdown  # noqa: E402
from scipy.interpolate import CubicSpline  # noqa: E402
from scipy.signal import welch  # noqa: E402

from convsynth_jax.cdbn.features import head_rotation, head_rotation_from_quat, speech_features  # noqa: E402
from convsynth_jax.cdbn.residual import draw_residual  # noqa: E402
from convsynth_jax.cdbn.synthesize import body_excerpt, expected_motion, keypoint_smooth, sample_motion, state_posteriors  # noqa: E402
from convsynth_jax.evaluation.field.fgd import fgd, raw_window_features  # noqa: E402
from convsynth_jax.evaluation.field.kinematic import average_jerk  # noqa: E402
from convsynth_jax.evaluation.field.params import FieldMetricParams  # noqa: E402
from convsynth_jax.evaluation.loo import fit_fold, session_windows, training_clips, window_input  # noqa: E402
from convsynth_jax.api import cache_dir  # noqa: E402

BANDS = ((0.0, 1.0), (1.0, 3.0), (3.0, 7.5), (7.5, 15.01))


def keys_of(T: int, fps: float, rate: float) -> np.ndarray:
    step = max(fps / rate, 1.0)
    return np.unique(np.concatenate([np.round(np.arange(0, T - 1, step)).astype(int), [T - 1]]))


def kp(angles, fps, rate):
    return head_rotation_from_quat(keypoint_smooth(angles, fps, rate))


def kp_euler(angles, fps, rate):
    k = keys_of(len(angles), fps, rate)
    t = np.arange(len(angles))
    return np.stack([np.interp(t, k, angles[k, d]) for d in range(angles.shape[1])], axis=1)


def jerk(angles, fps):
    return average_jerk(np.asarray(angles)[:, None, :], fps)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--folds", type=int, nargs="+", default=[0])
    ap.add_argument("--conditions", nargs="+", default=["cdbn", "jdbn"])
    ap.add_argument("--override", nargs="*", default=[])
    ap.add_argument("--name", default="cdbn_energy")
    args = ap.parse_args()
    t0 = time.perf_counter()
    over = ["system=cdbn", "cdbn.synth.residual=spectral", *args.override]
    params, ann, system = loo_setup(over)
    rate = system.cdbn.synth.keypoints_per_second
    names = list(ann)
    rng = np.random.default_rng(params.seed)
    jerks, sds, psd, feats = {}, {}, {}, {}
    fp = FieldMetricParams()

    def add(key, angles, fps):
        a = np.asarray(angles, np.float64)
        if fps == params.fps:   # raw FGD of the head angles (the head-rotation view), 30-frame windows
            feats.setdefault(key, []).append(raw_window_features(a[:, None, :], fp.fgd.raw_window_frames,
                                                                 fp.fgd.raw_frame_step))
        jerks.setdefault(key, []).append(jerk(a, fps))
        sds.setdefault(key, []).append(a.std(0))
        if fps == 30.0 or fps == params.fps:
            f, p = welch(a - a.mean(0), fs=fps, nperseg=min(128, len(a)), axis=0)
            psd.setdefault(key, []).append((f, p.sum(1)))

    def stages(prefix, a, fps):
        add(f"{prefix}_raw", a, fps)
        k = keys_of(len(a), fps, rate)
        add(f"{prefix}_keys", a[k], rate)
        add(f"{prefix}_kp15", kp(a, fps, rate), fps)
        add(f"{prefix}_kp15_euler", kp_euler(a, fps, rate), fps)
        t = np.arange(len(a)) / fps
        t4 = np.arange(4 * len(a) - 3) / (4 * fps)
        up = CubicSpline(t, a, axis=0)(t4)
        add(f"{prefix}_x120_raw", up, 4 * fps)
        add(f"{prefix}_x120_kp15", kp(up, 4 * fps, rate), 4 * fps)

    for fold in args.folds:
        for cond in args.conditions:
            fitted = fit_fold(system, ann, names[fold], cond, cache_dir(params))
            held = ann[names[fold]]
            for w in session_windows(held, params.fps, params.loo.window, params.loo.hop, params.loo.max_windows):
                for role, a in held.items():
                    win = window_input(held, role, w, params.fps, 0, with_audio=True)
                    n, fps = win.num_frames, win.fps
                    gt = head_rotation(a.motion.slice(win.start_frame, win.start_frame + n), system.cdbn.features)
                    try:
                        raw = speech_features(win.own_audio, system.cdbn.features, n, fps)
                    except Exception:   # a window the character barely speaks in: the system fails it too
                        continue
                    mdl = fitted[a.character]
                    tm, inv = mdl.trained.model, mdl.motion_norm.invert
                    sz = mdl.speech_norm.apply(raw)
                    cons = np.asarray(mdl.constraint_map, np.int32)[np.asarray(win.own_frames.label, np.int64)]
                    if not mdl.constrained:
                        cons = np.zeros(n, np.int32)
                    if cond == args.conditions[0]:
                        stages("gt", gt, fps)
                        body = body_excerpt([c.motion for c in training_clips(ann, names[fold], a.character)], n, rng)
                        add("random_playback", head_rotation(body, system.cdbn.features), fps)
                    for post in ("smoother", "viterbi"):
                        m = inv(expected_motion(tm, state_posteriors(tm, sz, cons, post)))
                        stages(f"{cond}_{post}", m, fps)
                        if post == "smoother":
                            smooth = m
                    mu, draw = sample_motion(tm, sz, cons, rng)
                    draw = inv(draw)
                    add(f"{cond}_draws_kp15", kp(draw, fps, rate), fps)
                    if mdl.residual is not None:
                        add(f"{cond}_spectral", kp(smooth, fps, rate) + draw_residual(mdl.residual, n, rng), fps)
            print(f"fold {fold} {cond}: {time.perf_counter() - t0:.0f} s", flush=True)
    g = float(np.mean(jerks["gt_raw"]))
    g120 = float(np.mean(jerks["gt_x120_raw"]))
    rows = {}
    for k, v in jerks.items():
        j = float(np.mean(v))
        ref = g120 if "x120" in k else g
        row = {"jerk_deg_s3": j, "jerk_over_gt_raw": j / ref, "sd_pitch_yaw_roll": np.mean(sds[k], 0).round(3).tolist(),
               "windows": len(v)}
        if k in feats:
            row["fgd_raw_head_angles"] = fgd(np.concatenate(feats[k]), np.concatenate(feats["gt_raw"]))
        if k in psd:
            f = psd[k][0][0]
            p = np.mean([pp for ff, pp in psd[k] if len(ff) == len(f)], axis=0)
            jp = p * (2 * np.pi * f) ** 6
            row["variance_share_by_band"] = [float(p[(f >= lo) & (f < hi)].sum() / p.sum()) for lo, hi in BANDS]
            row["jerk_power_share_by_band"] = [float(jp[(f >= lo) & (f < hi)].sum() / jp.sum()) for lo, hi in BANDS]
        rows[k] = row
    rp = rows["random_playback"]["fgd_raw_head_angles"]
    for r in rows.values():
        if "fgd_raw_head_angles" in r:
            r["fgd_over_random_playback"] = r["fgd_raw_head_angles"] / rp
    result = {"folds": args.folds, "conditions": args.conditions, "overrides": over, "keypoints_per_second": rate,
              "bands_hz": BANDS, "head_angles": rows, "note": "x120 rows are relative to gt_x120_raw",
              "seconds": time.perf_counter() - t0}
    write(args.name, result, overrides=over)
    lines = ["| variant | angular jerk (deg/s^3) | / recording | SD pitch, yaw, roll | jerk power 0-1 / 1-3 / 3-7.5 / 7.5-15 Hz "
             "| raw FGD (head angles) | / random playback |", "|---|---|---|---|---|---|---|"]
    for k, r in rows.items():
        bands = " / ".join(f"{x:.2f}" for x in r.get("jerk_power_share_by_band", []))
        lines.append(f"| {k} | {r['jerk_deg_s3']:.0f} | {r['jerk_over_gt_raw']:.2f} | "
                     f"{', '.join(f'{x:.2f}' for x in r['sd_pitch_yaw_roll'])} | {bands} | "
                     f"{r.get('fgd_raw_head_angles', float('nan')):.2f} | {r.get('fgd_over_random_playback', float('nan')):.2f} |")
    write_markdown(args.name, lines, overrides=over)


if __name__ == "__main__":
    main()
