"""The constrained DBN on a real recording: the BEAT2 take in ../shared/data/beat2 (one speaker, 63.5 s).

Leave-one-out needs two sessions and BEAT2's pseudo-dyad has one (its partner is the same take
rotated in time, so it cannot be training data for it). Instead the take is split in time into two
halves; each half in turn is held out and the CDBN / jDBN trains on the other half (speech from
the take's audio, constraints from the framework's own audio labels; labels absent from a monologue,
LR and HP, are mapped onto idle). The held-out half is cut into 10 s windows (5 s hop); per window:

* the head point's average jerk (the benchmark's head scope: the End Site above the head, global)
  and its ratio to the recording's over the same windows;
* the head rotation's angular jerk (Neck * Head, deg/s^3) and SD, ratio to the recording's;
* the raw FGD of the root-relative head point (30-frame windows every 10th frame) against the
  recording's same windows, and the same of the head angles. On this rig (SMPL-X) the head joint
  has children (jaw, eyes) and no End Site, so the head point is the head joint itself, which the
  head's own rotation does not move: the head-point figures see only the body, the head-angle
  figures see the head;

for the recording, random playback (an excerpt of the training half, drawn per window), and each
system variant: ``paper_still_body`` (cdbn.synth.body=mean, the former default), ``default`` (the
body from the training half), ``residual_only`` (plus cdbn.synth.residual=spectral), ``kp5`` (5 key
points per second instead of the paper's 15), ``match_jerk_only`` (cdbn.synth.match_jerk=true: the
rate chosen on the training half) and ``quality`` (both of preset=quality's CDBN options).

    python experiments/analysis/cdbn_beat2.py [--root ../shared/data/beat2]

Writes experiments/results/cdbn_beat2.json and .md (with manifests).
"""
import argparse
import sys
import time
from pathlib import Path
from types import SimpleNamespace

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))

import numpy as np  # noqa: E402
import yaml  # noqa: E402
from _bench import write, write_markdown  # noqa: E402

from convsynth_jax.cdbn.features import head_rotation  # noqa: E402
from convsynth_jax.cdbn.synthesize import body_excerpt  # noqa: E402
from convsynth_jax.config import CONFIG_DIR, default_params  # noqa: E402
from convsynth_jax.evaluation.field.fgd import fgd, raw_window_features  # noqa: E402
from convsynth_jax.evaluation.field.kinematic import average_jerk  # noqa: E402
from convsynth_jax.evaluation.field.params import FieldMetricParams  # noqa: E402
from convsynth_jax.evaluation.field.views import motion_view  # noqa: E402
from convsynth_jax.io.audio import Audio, load_audio  # noqa: E402
from convsynth_jax.kinematics import jerk  # noqa: E402
from convsynth_jax.systems.base import SystemParams, make_system  # noqa: E402
from convsynth_jax.api import annotated_corpus  # noqa: E402

VARIANTS = {"paper_still_body": {"synth": {"body": "mean"}}, "default": {},
            "residual_only": {"synth": {"residual": "spectral"}},
            "kp5": {"synth": {"keypoints_per_second": 5.0}},
            "match_jerk_only": {"synth": {"match_jerk": True}},
            "quality": {"synth": {"residual": "spectral", "match_jerk": True}}}
CMAP = {"LR": "idle", "HP": "idle"}


def angular_jerk(a, fps):
    return float(np.linalg.norm(jerk(np.asarray(a, np.float64), fps), axis=1).mean())


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--root", default=str(Path(__file__).resolve().parents[3] / "shared" / "data" / "beat2"))
    ap.add_argument("--window", type=float, default=10.0)
    ap.add_argument("--hop", type=float, default=5.0)
    args = ap.parse_args()
    t0 = time.perf_counter()
    over = ["corpus=beat2", f"corpus.root={args.root}", "system=cdbn"]
    params = default_params(over)
    _, ann = annotated_corpus(params)
    session = sorted(ann)[0]
    a = ann[session]["main-agent"]
    fps = float(a.motion.fps)
    F = a.motion.num_frames
    aud = load_audio(a.audio_path, channel=a.audio_channel)
    labels = np.asarray(a.own.label, np.int64)
    fp = FieldMetricParams()
    with open(f"{CONFIG_DIR}/system/cdbn.yaml") as fh:
        spec = yaml.safe_load(fh)
    hj = params.cdbn.features

    def audio_of(f0, f1):
        s0, s1 = round(f0 / fps * aud.sample_rate), round(f1 / fps * aud.sample_rate)
        return Audio(aud.samples[s0:s1], aud.sample_rate)

    def clip(f0, f1):
        return SimpleNamespace(motion=a.motion.slice(f0, f1), audio=audio_of(f0, f1), own=labels[f0:f1],
                               character=a.character, session=f"{session}[{f0}:{f1}]")

    half = F // 2
    folds = [((half, F), (0, half)), ((0, half), (half, F))]   # (train, test) frame ranges
    stats = {}
    rng = np.random.default_rng(params.seed)

    def add(key, motion, gt_angles=None):
        v = motion_view(motion, "head", fp.joints, params.annotate)
        ang = head_rotation(motion, hj)
        s = stats.setdefault(key, {"jerk": [], "ang_jerk": [], "ang_sd": [], "feats": [], "ang_feats": []})
        s["ang_feats"].append(raw_window_features(ang[:, None, :], fp.fgd.raw_window_frames, fp.fgd.raw_frame_step))
        s["jerk"].append(average_jerk(v.global_positions, fps))
        s["ang_jerk"].append(angular_jerk(ang, fps))
        s["ang_sd"].append(float(ang.std(0).mean()))
        s["feats"].append(raw_window_features(v.relative, fp.fgd.raw_window_frames, fp.fgd.raw_frame_step))

    fit_seconds, rates = {}, {}
    for (tr0, tr1), (te0, te1) in folds:
        train = clip(tr0, tr1)
        systems = {}
        for cond in ("cdbn", "jdbn"):
            for var, opts in VARIANTS.items():
                sysm = make_system(params, SystemParams(**{**spec, "options": {**opts, "constraint_map": CMAP}}))
                t1 = time.perf_counter()
                systems[f"{cond}_{var}"] = (sysm, sysm.fit([train], a.character, cond), cond)
                rates.setdefault(f"{cond}_{var}", []).append(systems[f"{cond}_{var}"][1].keypoints_per_second)
                fit_seconds.setdefault(f"{cond}_{var}", []).append(time.perf_counter() - t1)
        n = int(round(args.window * fps))
        for k, f0 in enumerate(range(te0, te1 - n + 1, int(round(args.hop * fps)))):
            gt = a.motion.slice(f0, f0 + n)
            add("ground_truth", gt)
            add("random_playback", body_excerpt([train.motion], n, rng))
            win = SimpleNamespace(session=session, role="main-agent", character=a.character, start_frame=f0,
                                  num_frames=n, fps=fps, own_frames=labels[f0:f0 + n], own_audio=audio_of(f0, f0 + n),
                                  seed=int(params.seed) * 1000 + f0)
            for key, (sysm, model, cond) in systems.items():
                res = sysm.synthesize(model, win, cond)
                if not res.success:
                    print(f"{key} window at frame {f0}: {res.failure}")
                    continue
                add(key, res.motion)
        print(f"fold test {te0}-{te1}: {time.perf_counter() - t0:.0f} s", flush=True)
    ref = np.concatenate(stats["ground_truth"]["feats"])
    ref_ang = np.concatenate(stats["ground_truth"]["ang_feats"])
    g = {k: float(np.mean(stats["ground_truth"][k])) for k in ("jerk", "ang_jerk", "ang_sd")}
    rows = {}
    for key, s in stats.items():
        rows[key] = {"windows": len(s["jerk"]), "head_point_jerk": float(np.mean(s["jerk"])),
                     "head_point_jerk_over_gt": float(np.mean(s["jerk"])) / g["jerk"],
                     "head_angle_jerk_over_gt": float(np.mean(s["ang_jerk"])) / g["ang_jerk"],
                     "head_angle_sd_over_gt": float(np.mean(s["ang_sd"])) / g["ang_sd"],
                     "fgd_raw_head": fgd(np.concatenate(s["feats"]), ref),
                     "fgd_raw_head_angles": fgd(np.concatenate(s["ang_feats"]), ref_ang)}
    rp = rows["random_playback"]["fgd_raw_head"]
    rpa = rows["random_playback"]["fgd_raw_head_angles"]
    for r in rows.values():
        r["fgd_over_random_playback"] = r["fgd_raw_head"] / rp if rp > 0 else float("nan")
        r["fgd_angles_over_random_playback"] = r["fgd_raw_head_angles"] / rpa if rpa > 0 else float("nan")
    result = {"take": session, "frames": F, "fps": fps, "window_s": args.window, "hop_s": args.hop,
              "protocol": "two halves in time, each held out once", "constraint_map": CMAP, "variants": VARIANTS,
              "rows": rows, "fit_seconds_mean": {k: float(np.mean(v)) for k, v in fit_seconds.items()},
              "keypoints_per_second_per_fold": rates,
              "seconds": time.perf_counter() - t0}
    write("cdbn_beat2", result, overrides=over)
    lines = ["| system | windows | head-point jerk / GT | head-angle jerk / GT | head-angle SD / GT | raw FGD (head point) "
             "| / random playback | raw FGD (head angles) | / random playback |", "|---|---|---|---|---|---|---|---|---|"]
    lines += [f"| {k} | {r['windows']} | {r['head_point_jerk_over_gt']:.2f} | {r['head_angle_jerk_over_gt']:.2f} | "
              f"{r['head_angle_sd_over_gt']:.2f} | {r['fgd_raw_head']:.1f} | {r['fgd_over_random_playback']:.2f} | "
              f"{r['fgd_raw_head_angles']:.2f} | {r['fgd_angles_over_random_playback']:.2f} |" for k, r in rows.items()]
    write_markdown("cdbn_beat2", lines, overrides=over)


if __name__ == "__main__":
    main()
