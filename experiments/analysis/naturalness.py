"""Where the motion graph's naturalness is lost, with a control for each cause (``preset=quality``).

On a few leave-one-out folds of the configured corpus, per window and character, for the motion
graph (condition ``all``), random playback (condition ``none``) and random playback whose excerpts
are as long as the motion graph's runs between synthetic transitions (the transition-frequency
control, ``--matched``), and the recordings of the same windows:

* still frames: mean speed of the body joints (fingers out, root-relative) below ``--still`` units/s
  (2 cm/s), and where each comes from: inside a retiming stretch (``synth/retime.py``: the warp
  shows path time more slowly than 0.75x), a window solved best-effort (a relaxed path), a source
  frame shown twice or more in a row (a continuation hold), or a still source frame (the recording
  itself is still there);
* source-frame visits: entropy of the visited (clip, second) cells, share of output frames whose
  source frame is still (the rest poses), share of frames from the window's most used clip, and how
  many times the same source second is revisited;
* transitions per window (synthetic transitions of the path, excerpt jumps of random playback);
* pose std per joint (root-relative, heading-free body positions) over the windows against the
  recordings' (median ratio per character).

    python experiments/analysis/naturalness.py [--folds 0 1] [--override ...]

Writes experiments/results/naturalness.json and .md (with manifests).
"""
import argparse
import dataclasses
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))

import numpy as np  # noqa: E402
from _bench import write, write_markdown  # noqa: E402

from convsynth_jax.config import default_params  # noqa: E402
from convsynth_jax.evaluation.field.params import FieldMetricParams  # noqa: E402
from convsynth_jax.evaluation.field.views import motion_view  # noqa: E402
from convsynth_jax.evaluation.loo import fit_fold, session_windows, window_input  # noqa: E402
from convsynth_jax.synth.retime import warp_times  # noqa: E402
from convsynth_jax.systems.base import SystemParams, make_system  # noqa: E402
from convsynth_jax.tasks.common import annotated_corpus, cache_dir  # noqa: E402

FP = FieldMetricParams()


def body_speed(motion, annotate) -> np.ndarray:
    """(F,) mean speed of the body joints (root-relative, heading-free), units/s."""
    rel = motion_view(motion, "body", FP.joints, annotate).relative
    v = np.linalg.norm(np.gradient(rel, axis=0), axis=-1) * motion.fps
    return v.mean(1)


def visits(clips, frames, fps, source_still) -> dict:
    cells = [(c, int(f // fps)) for c, f in zip(clips, frames)]
    _, counts = np.unique(np.array([f"{c}:{s}" for c, s in cells]), return_counts=True)
    p = counts / counts.sum()
    _, per_clip = np.unique(np.asarray(clips), return_counts=True)
    runs = np.flatnonzero(np.diff(np.asarray(frames)) != 1) + 1
    segs = np.split(np.arange(len(frames)), runs)
    seconds = [frozenset(int(frames[i] // fps) for i in s) for s in segs]
    seen, revisits = {}, 0
    for s, seg in zip(seconds, segs):
        key = (clips[seg[0]], s)
        for sec in s:
            revisits += int(seen.get((key[0], sec), False))
            seen[(key[0], sec)] = True
    return {"entropy_bits": float(-(p * np.log2(p)).sum()), "source_still_share": float(np.mean(source_still)),
            "top_clip_share": float(per_clip.max() / len(clips)), "revisited_seconds": revisits}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--folds", type=int, nargs="+", default=[0, 1])
    ap.add_argument("--still", type=float, default=2.0)
    ap.add_argument("--override", nargs="*", default=[])
    args = ap.parse_args()
    t0 = time.perf_counter()
    over = ["preset=quality", *args.override]
    params = default_params(over)
    _, ann = annotated_corpus(params)
    names = list(ann)
    mg = make_system(params, params.system)
    rp_spec = SystemParams(name="random_playback", factory="convsynth_jax.systems.random_playback:RandomPlaybackSystem",
                           conditions={"none": {}}, options={})
    rp = make_system(params, rp_spec)
    speeds = {}                 # label -> character -> list of (F,) speeds
    poses = {}                  # label -> character -> list of (F, P*3) relative positions
    rows = {"motion_graph": [], "random_playback": [], "random_playback_matched": []}
    still_src = {}
    cd = cache_dir(params)

    def record(label, char, motion):
        speeds.setdefault(label, {}).setdefault(char, []).append(body_speed(motion, params.annotate))
        rel = motion_view(motion, "body", FP.joints, params.annotate).relative
        poses.setdefault(label, {}).setdefault(char, []).append(rel.reshape(len(rel), -1))

    for fold in args.folds:
        fm = fit_fold(mg, ann, names[fold], "all", cd)
        fr = fit_fold(rp, ann, names[fold], "none", cd)
        held = ann[names[fold]]
        for w in session_windows(held, params.fps, params.loo.window, params.loo.hop, params.loo.max_windows):
            for k, (role, a) in enumerate(held.items()):
                win = window_input(held, role, w, params.fps, 1000 * fold + 10 * w.index + k)
                n, fps = win.num_frames, win.fps
                char = a.character
                record("recordings", char, a.motion.slice(win.start_frame, win.start_frame + n))
                res = mg.synthesize(fm[char], win, "all")
                if not res.success:
                    rows["motion_graph"].append({"failed": True})
                    continue
                motions = fm[char].motions
                for c in set(res.source_clip):
                    if (char, c) not in still_src:
                        still_src[(char, c)] = body_speed(motions[c], params.annotate) < args.still
                src_still = np.array([still_src[(char, c)][f] for c, f in zip(res.source_clip, res.source_frame)])
                sp = body_speed(res.motion, params.annotate)
                still = sp < args.still
                d = res.diagnostics
                warp = d.get("warp")
                slow = np.zeros(n, bool)
                if warp is not None:
                    tau = warp_times(n, *warp)
                    slow = np.gradient(tau) < 0.75
                fr_ = np.asarray(res.source_frame)
                held_frame = np.r_[False, (fr_[1:] == fr_[:-1])]
                transitions = int(d.get("num_synthetic_transitions") or 0)
                rows["motion_graph"].append({
                    "failed": False, "still": float(still.mean()), "transitions": transitions,
                    "best_effort": bool(d.get("best_effort")),
                    "still_in_retime_stretch": float((still & slow).mean()),
                    "still_in_best_effort": float(still.mean()) if d.get("best_effort") else 0.0,
                    "still_on_held_source": float((still & held_frame).mean()),
                    "still_on_still_source": float((still & src_still).mean()),
                    "retime_slow_share": float(slow.mean()), **visits(res.source_clip, fr_, fps, src_still)})
                record("motion_graph", char, res.motion)
                for label, opts in (("random_playback", {}),
                                    ("random_playback_matched", {"min_excerpt_seconds": n / fps / (transitions + 1),
                                                                 "max_excerpt_seconds": n / fps / (transitions + 1)})):
                    rp.system = dataclasses.replace(rp_spec, options=opts)
                    r = rp.synthesize(fr[char], win, "none")
                    ss = np.array([still_src.setdefault((char, c), body_speed(fr[char].motions[c], params.annotate)
                                                        < args.still)[f] for c, f in zip(r.source_clip, r.source_frame)])
                    sp = body_speed(r.motion, params.annotate)
                    rows[label].append({"failed": False, "still": float((sp < args.still).mean()),
                                        "transitions": len(r.synthetic_at or []),
                                        **visits(r.source_clip, np.asarray(r.source_frame), fps, ss)})
                    record(label, char, r.motion)
        print(f"fold {fold}: {time.perf_counter() - t0:.0f} s", flush=True)
    summary = {}
    for label, rs in rows.items():
        ok = [r for r in rs if not r["failed"]]
        keys = [k for k in ok[0] if k != "failed"] if ok else []
        summary[label] = {"windows": len(rs), "failed": len(rs) - len(ok),
                          **{k: float(np.mean([r[k] for r in ok])) for k in keys}}
    ref = {c: np.concatenate(v).std(0) for c, v in poses["recordings"].items()}
    pose_std = {label: {c: float(np.median(np.concatenate(v).std(0) / np.maximum(ref[c], 1e-9))) for c, v in d.items()}
                for label, d in poses.items()}
    still_rec = float(np.mean(np.concatenate([np.concatenate(v) for v in speeds["recordings"].values()]) < args.still))
    result = {"folds": args.folds, "overrides": over, "still_threshold": args.still, "systems": summary,
              "pose_std_over_recordings_median": pose_std, "recordings_still": still_rec,
              "seconds": time.perf_counter() - t0}
    write("naturalness", result, overrides=over)
    keys = sorted({k for s in summary.values() for k in s})
    lines = ["| measure | " + " | ".join(summary) + " |", "|---|" + "---|" * len(summary)]
    lines += [f"| {k} | " + " | ".join(f"{s.get(k, float('nan')):.3g}" for s in summary.values()) + " |" for k in keys]
    lines += ["", f"recordings: still share {still_rec:.3g}", "", "| pose std / recordings (median over joints) | "
              + " | ".join(sorted(ref)) + " |", "|---|" + "---|" * len(ref)]
    lines += [f"| {lab} | " + " | ".join(f"{d[c]:.3f}" for c in sorted(ref)) + " |" for lab, d in pose_std.items()]
    write_markdown("naturalness", lines, overrides=over)


if __name__ == "__main__":
    main()
