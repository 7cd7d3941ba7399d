"""Benchmark: generate the default synthetic corpus (17 sessions, 30 minutes, audio included).
Goal: under 60 s. Also times the same corpus without audio (the difference is the cost of
synthesizing and writing 2 x 30 minutes of 16 kHz speech), counts the planted events and measures
what makes the corpus hard (README "The synthetic corpus"):

* realized co-occurrence rates vs the configured Table 1 rates: causal (share of segments that caused
  a movement), as the annotation pipeline's detector and counter see the written motion over the
  planted audio segments (``realized_detector``: the BVH files read back, ``joint_speeds``, Eq. 1
  thresholds per recording, ``stats.cooccurrence.hypothesis_matches``; what the generator calibrates
  against by default), and as ``window_matches`` sees the planted movement intervals
  (``realized_window``, the old calibration target), with the generator's calibration report;
* words per pause-free stretch (pause: >= 0.2 s between consecutive words of one speaker),
  overlapping speech, coarticulated gestures, glitches.

Writes experiments/results/bench_synthetic.json.

    python experiments/bench/bench_synthetic.py [--no-audio-run-only]
"""
import argparse
import json
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from convsynth_jax.annotate.motion import joint_speeds, recording_thresholds
from convsynth_jax.annotate.params import AnnotateParams
from convsynth_jax.config import compose
from convsynth_jax.data import make_synthetic_corpus
from convsynth_jax.data.synthetic import HYPOTHESIS_KEYS, ROLES, window_matches
from convsynth_jax.io import load_bvh
from convsynth_jax.stats.cooccurrence import hypothesis_matches
from convsynth_jax.api import timed, write_result


def detector_counts(root: Path, ev: pd.DataFrame) -> dict:
    """{(role, hypothesis): [matched, total]} by the annotation pipeline's detector and counter on the
    written BVH files, over the planted audio segments (events.csv)."""
    ap = AnnotateParams()
    out = {}
    for s, e in ev.groupby("session"):
        segs = {r: e[(e.participant == r) & e.kind.isin(["PC", "LR", "HP"])].sort_values("start") for r in ROLES}
        for k, role in enumerate(ROLES):
            motion = load_bvh(root / f"{s}_{role}.bvh")
            speeds = joint_speeds(motion, ap)
            thr = recording_thresholds(speeds, ap.alpha_s)
            for h in HYPOTHESIS_KEYS:
                hit, _ = hypothesis_matches(speeds, segs[role], segs[ROLES[1 - k]], motion.fps, h, thresholds=thr,
                                            alpha_w=ap.alpha_w, extend_trim=ap.extend_trim)
                c = out.setdefault((role, h), [0, 0])
                c[0] += int(hit.sum())
                c[1] += int(hit.size)
    return out


def realized_rates(root: Path) -> list[dict]:
    ev = pd.read_csv(root / "events.csv")
    ev["source"] = ev["source"].fillna("")
    cfg = json.loads((root / "corpus.json").read_text())["config"]
    det = detector_counts(root, ev)
    rows = []
    for role in ROLES:
        for h, (akind, kinds, whose, key) in HYPOTHESIS_KEYS.items():
            owner = role if whose == "own" else ROLES[1 - ROLES.index(role)]
            hit = n = 0
            for _, e in ev.groupby("session"):
                chan = e[(e.participant == owner) & e.kind.isin(["PC", "LR", "HP"])]
                mv = e[(e.participant == role) & e.kind.isin(kinds)]
                audio = chan[chan.kind == akind]
                hit += int(window_matches(audio[["start", "end"]].values, chan[["start", "end"]].values,
                                          mv[["start", "end"]].values).sum())
                n += len(audio)
            caused = ev[(ev.participant == role) & (ev.source == akind) & ev.kind.isin(kinds)]
            causal = caused.groupby(["session", "cause_start"]).ngroups / max(n, 1)
            conf = cfg["characters"][role][key]
            d_hit, d_n = det[(role, h)]
            rows.append({"character": cfg["characters"][role]["name"], "hypothesis": h, "segments": n,
                         "configured": conf, "realized_detector": d_hit / max(d_n, 1),
                         "realized_window": hit / max(n, 1), "realized_causal": causal,
                         "detector_minus_configured_pp": 100 * (d_hit / max(d_n, 1) - conf),
                         "window_minus_configured_pp": 100 * (hit / max(n, 1) - conf)})
    return rows


def difficulty(root: Path) -> dict:
    ev = pd.read_csv(root / "events.csv")
    words, overlap, speech = [], 0.0, 0.0
    for s in sorted(ev.session.unique()):
        grids = []
        for r in ROLES:
            w = pd.read_csv(root / f"{s}_{r}.tsv", sep="\t", header=None, names=["start", "end", "word"])
            brk = np.flatnonzero(w.start.values[1:] - w.end.values[:-1] >= 0.2)
            words += list(np.diff(np.concatenate([[0], brk + 1, [len(w)]])))
            g = np.zeros(int(w.end.max() * 100) + 200, bool)
            for a, b in zip(w.start, w.end):
                g[int(a * 100):int(b * 100)] = True
            grids.append(g)
        n = min(len(g) for g in grids)
        overlap += float((grids[0][:n] & grids[1][:n]).sum()) / 100
        speech += float((grids[0][:n] | grids[1][:n]).sum()) / 100
    words = np.array(words)
    multi = words[words > 1]  # stretches that are not a lone response or filler
    pc, lr = ev[ev.kind == "PC"], ev[ev.kind == "LR"]
    lr_over = np.mean([((pc.session == r.session) & (pc.participant != r.participant) & (pc.start < r.end)
                        & (pc.end > r.start)).any() for r in lr.itertuples()])
    turn_over = np.mean([((pc.session == r.session) & (pc.participant != r.participant) & (pc.start < r.start)
                          & (pc.end > r.start)).any() for r in pc.itertuples()])
    adj = tot = 0
    for _, g in ev[ev.kind.isin(["LH", "RH"])].groupby(["session", "participant", "kind"]):
        g = g.sort_values("start")
        d = g.start.values[1:] - g.end.values[:-1]
        adj += int((np.abs(d) < 1e-3).sum())
        tot += d.size
    gl = pd.read_csv(root / "glitches.csv")
    hist = np.bincount(np.minimum(words, 20))
    return {"words_per_pause_free_stretch": {
                "all": {"mean": float(words.mean()), "median": float(np.median(words)),
                        "p90": float(np.percentile(words, 90)), "max": int(words.max()), "count": int(words.size)},
                "excluding_one_word": {"mean": float(multi.mean()), "median": float(np.median(multi)),
                                       "p90": float(np.percentile(multi, 90))},
                "histogram_1_to_20plus": hist[1:].tolist()},
            "clauses_per_pause_free_stretch_mean": float(len(pc) / max(1, int((words > 1).sum()))),
            "overlapping_speech_share_of_speech_time": overlap / speech,
            "listener_responses_over_partner_clause": float(lr_over),
            "clauses_starting_inside_partner_clause": float(turn_over),
            "same_hand_gesture_pairs_coarticulated": adj / max(tot, 1), "same_hand_gesture_pairs": tot,
            "glitches": int(len(gl)), "glitches_by_kind": gl.kind.value_counts().to_dict()}


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--keep", help="write the corpus with audio here (kept) instead of a temporary folder")
    args = ap.parse_args()
    cfg = compose([])
    gen = cfg.corpus.generator
    with tempfile.TemporaryDirectory() as d:
        target = Path(args.keep) if args.keep else Path(d) / "c"
        root, secs = timed(make_synthetic_corpus, target, gen)
        size = sum(p.stat().st_size for p in root.iterdir()) / 1e6
        ev = pd.read_csv(root / "events.csv")
        rates = realized_rates(root)
        hard = difficulty(root)
        calibration = json.loads((root / "corpus.json").read_text()).get("calibration", {})
        _, secs_no_audio = timed(make_synthetic_corpus, Path(d) / "n", {**dict(gen), "write_audio": False})
    counts = ev.assign(source=ev["source"].fillna("")).groupby(["participant", "kind", "source"]).size()
    print(pd.DataFrame(rates).to_string(index=False))
    write_result("bench_synthetic", {"sessions": gen.num_sessions, "minutes": gen.num_sessions * gen.session_seconds / 60,
                              "seconds": secs, "seconds_without_audio": secs_no_audio,
                              "audio_seconds": secs - secs_no_audio, "megabytes": size, "goal_s": 60,
                              "events": {" ".join(k).strip(): int(v) for k, v in counts.items()},
                              "realized_rates": rates,
                              "max_abs_detector_minus_configured_pp": max(abs(r["detector_minus_configured_pp"])
                                                                          for r in rates),
                              "max_abs_window_minus_configured_pp": max(abs(r["window_minus_configured_pp"]) for r in rates),
                              "calibration": calibration, "difficulty": hard})
