"""Statistics of a written synthetic corpus (docs/synthetic_corpus.md): the co-occurrence rates it
realizes against the configured ones, and what makes it hard. ``experiments/bench/bench_synthetic.py``
reports them beside the generation time."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from ...annotate.motion import joint_speeds, recording_thresholds
from ...annotate.params import AnnotateParams
from ...io import load_bvh
from ...stats.cooccurrence import hypothesis_matches
from .calibration import HYPOTHESIS_KEYS, window_matches
from .config import ROLES


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
    """Per character and hypothesis, the co-occurrence rate the written corpus realizes against the
    configured one: causal (share of the audio segments that caused a movement), as the annotation
    pipeline's detector and counter see the written motion (``realized_detector``, what the generator
    calibrates against by default) and as ``window_matches`` sees the planted movement intervals
    (``realized_window``, the old calibration target)."""
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
    """What makes the corpus hard: words per pause-free stretch (pause: >= 0.2 s between consecutive
    words of one speaker), clauses per stretch, overlapping speech, listener responses over the
    partner's clause, clauses starting inside the partner's, coarticulated same-hand gestures, glitches."""
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
