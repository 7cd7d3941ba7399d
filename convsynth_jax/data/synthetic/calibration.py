"""Calibration of the planting probabilities (``planting_probabilities``): the realized co-occurrence
rates of a planned corpus, measured as the annotation pipeline's detector counts them or as the
paper's windows see the planted intervals, are moved onto the configured ones (paper Table 1)."""
from __future__ import annotations

import copy

import numpy as np
import pandas as pd

from ...annotate.kinds import hypotheses
from .config import ROLES, detector_settings
from .conversation import Segment
from .plan import _plan, _quota_offsets, _render_motion


# hypothesis -> (audio kind, motion kinds, channel, planting probability key), from the registry
HYPOTHESIS_KEYS = {h.name: (h.label, h.motions, h.channel, h.planting) for h in hypotheses()}
CORE = 0.0  # a movement counts on [start + CORE * length, end - CORE * length] (window matching; 0: all of it,
# which is what the annotation pipeline's nod detection reproduces on the default corpus)


def window_matches(audio: np.ndarray, channel: np.ndarray, movements: np.ndarray) -> np.ndarray:
    """Which audio segments co-occur with a movement, as the paper's windows see it (Figure 3).

    audio: (N, 2) [start, end] seconds of the hypothesis' audio segments; channel: (M, 2) every audio
    segment of that channel (the neighbours that trim a window); movements: (K, 2) [start, end] of the
    participant's movements of the hypothesis' kinds. A window is the segment doubled around its
    centre, trimmed to the neighbouring segments; windows are visited in time order and each starts
    no earlier than the end of the movement matched by the previous one; a window is matched when the
    core of a movement (``CORE``) overlaps it. Returns (N,) bool in the order of ``audio``."""
    audio, channel, movements = (np.asarray(x, float).reshape(-1, 2) for x in (audio, channel, movements))
    length = movements[:, 1] - movements[:, 0]
    core = np.stack([movements[:, 0] + CORE * length, movements[:, 1] - CORE * length], 1)
    out = np.zeros(len(audio), bool)
    last_end = -np.inf
    for i in np.argsort(audio[:, 0], kind="stable"):
        s, e = audio[i]
        lo, hi = s - (e - s) / 2, e + (e - s) / 2
        prev = channel[(channel[:, 1] <= s + 1e-9) & (channel[:, 0] < s - 1e-9), 1]
        nxt = channel[(channel[:, 0] >= e - 1e-9) & (channel[:, 1] > e + 1e-9), 0]
        lo = max(lo, prev.max()) if prev.size else lo
        hi = min(hi, nxt.min()) if nxt.size else hi
        lo = max(lo, last_end)
        hit = (core[:, 0] < hi) & (core[:, 1] > lo)
        if hi > lo and hit.any():
            out[i] = True
            last_end = movements[hit, 1].max()
    return out


def _plan_matches(plan: dict, role: str, hypothesis: str) -> tuple[np.ndarray, np.ndarray]:
    """(matched, caused) flags over the hypothesis' audio segments of one planned session, matched as
    ``window_matches`` sees the planted movement intervals (``calibrate_against="windows"``)."""
    akind, kinds, whose, _ = HYPOTHESIS_KEYS[hypothesis]
    owner = role if whose == "own" else ROLES[1 - ROLES.index(role)]
    chan = [sg for sg in plan["segs"] if sg.role == owner]
    audio = [sg for sg in chan if sg.kind == akind]
    evs = [e for e in plan["events"][role] if e["kind"] in kinds]
    m = window_matches([(a.start, a.end) for a in audio], [(c.start, c.end) for c in chan],
                       [(e["start"], e["end"]) for e in evs])
    return m, _caused(plan, role, hypothesis, audio)


def _caused(plan: dict, role: str, hypothesis: str, audio: list[Segment]) -> np.ndarray:
    """Which of the ``audio`` segments caused a movement of the hypothesis' kinds of ``role``."""
    akind, kinds, _, _ = HYPOTHESIS_KEYS[hypothesis]
    caused = {e.get("cause_start") for e in plan["events"][role] if e["kind"] in kinds and e["source"] == akind}
    return np.array([a.start in caused for a in audio], bool)


def _segment_frame(segs: list[Segment]) -> tuple[pd.DataFrame, list[Segment]]:
    """DataFrame[kind, start, end] of one participant's segments, in time order, and those segments."""
    segs = sorted(segs, key=lambda sg: sg.start)
    return pd.DataFrame({"kind": [sg.kind for sg in segs], "start": [sg.start for sg in segs],
                         "end": [sg.end for sg in segs]}), segs


def _detector_matches(plan: dict, cfg: dict) -> dict:
    """{(role, hypothesis): (matched, caused)} of one planned session as the annotation pipeline counts
    it (``calibrate_against="detector"``): each participant's motion is rendered exactly as it will be
    written, its joint speeds and Eq. 1 recording thresholds computed, and every hypothesis counted by
    ``stats.cooccurrence.hypothesis_matches`` over the planted audio segments (Table 1 counts over the
    detected ones; the two differ where clause segmentation does)."""
    from ...annotate.motion import joint_speeds, recording_thresholds
    from ...annotate.params import AnnotateParams
    from ...stats.cooccurrence import hypothesis_matches

    st = detector_settings()
    ap = AnnotateParams(alpha_s=st["alpha_s"], alpha_w=st["alpha_w"], extend_trim=st["extend_trim"],
                        up_axis=st["up_axis"])
    frames = {r: _segment_frame([sg for sg in plan["segs"] if sg.role == r]) for r in ROLES}
    out = {}
    for k, role in enumerate(ROLES):
        motion, _ = _render_motion(plan, role, cfg)
        speeds = joint_speeds(motion, ap)
        thr = recording_thresholds(speeds, ap.alpha_s)
        (own, own_segs), (partner, partner_segs) = frames[role], frames[ROLES[1 - k]]
        for h, (akind, _, whose, _) in HYPOTHESIS_KEYS.items():
            hit, _ = hypothesis_matches(speeds, own, partner, motion.fps, h, thresholds=thr, alpha_w=ap.alpha_w,
                                        extend_trim=ap.extend_trim)
            audio = [sg for sg in (own_segs if whose == "own" else partner_segs) if sg.kind == akind]
            out[(role, h)] = (hit, _caused(plan, role, h, audio))
    return out


def _window_matches_all(plan: dict, cfg: dict) -> dict:
    return {(r, h): _plan_matches(plan, r, h) for r in ROLES for h in HYPOTHESIS_KEYS}


# how the calibration measures a planned session's realized rates (generator key calibrate_against)
CALIBRATION_MEASURES = {"detector": _detector_matches, "windows": _window_matches_all}


def planting_probabilities(cfg: dict) -> tuple[dict, dict]:
    """Per role the probabilities to plant with, and a report. Without ``calibrate_rates`` the
    configured ones. With it: movements that belong to other segments (a gesture of the next clause,
    a nod for a listener response) or spontaneous ones also land in windows of segments that caused
    nothing, at a rate q, and a share m of the causing segments' windows miss their movement (the
    previous window's movement runs into them, or it was dropped for coming too close to another),
    so the realized window rate is about p' (1 - m) + (1 - p') q. The realized rates are measured on
    this very corpus (same seed and conversations) by ``calibrate_against``: ``detector`` renders the
    motion and counts with the annotation pipeline's detector and counter (``_detector_matches``),
    ``windows`` counts the planned movement intervals (``window_matches``, no rendering). p' is moved
    by the remaining error, p' <- p' + (p - realized(p')) (planting is nested in p', see
    ``_plant_events``, so nearby p' give nearby corpora and the full step converges in a few passes),
    for ``calibration_passes`` passes or until every realized rate is within
    ``calibration_tolerance`` of the configured one. Since the corpus is a deterministic
    function of p', the pass with the smallest largest error is the corpus that gets written; the
    report gives each pass's p', realized rates, q and m, and the chosen pass."""
    conf = {r: {HYPOTHESIS_KEYS[h][3]: float(cfg["characters"][r][HYPOTHESIS_KEYS[h][3]]) for h in HYPOTHESIS_KEYS}
            for r in ROLES}
    if not cfg["calibrate_rates"]:
        return conf, {}
    measure = CALIBRATION_MEASURES[cfg["calibrate_against"]]
    probs, report = copy.deepcopy(conf), {"measure": cfg["calibrate_against"], "passes": []}
    if cfg["calibrate_against"] == "detector":
        report["detector"] = detector_settings()
    offsets = _quota_offsets(cfg)
    best = (np.inf, conf)
    for _ in range(int(cfg["calibration_passes"])):
        flags = [measure(_plan(i, cfg, probs, offsets), cfg) for i in range(int(cfg["num_sessions"]))]
        new, rows, worst = copy.deepcopy(conf), {}, 0.0
        for r in ROLES:
            for h, (_, _, _, key) in HYPOTHESIS_KEYS.items():
                m = np.concatenate([f[(r, h)][0] for f in flags])
                c = np.concatenate([f[(r, h)][1] for f in flags])
                q = float(m[~c].mean()) if (~c).any() else 0.0
                miss = float(1.0 - m[c].mean()) if c.any() else 0.0
                realized = float(m.mean()) if m.size else conf[r][key]
                worst = max(worst, abs(realized - conf[r][key]))
                # fixed-point step: shift p' by the remaining error of the realized rate
                new[r][key] = float(np.clip(probs[r][key] + conf[r][key] - realized, 0.0, 1.0))
                rows[f"{r} {h}"] = {"planted_with": round(probs[r][key], 4), "realized": round(realized, 4),
                                    "q": round(q, 4), "miss": round(miss, 4)}
            pr = new[r]  # keep the PC probabilities consistent: max(lh, rh) <= either <= lh + rh
            pr["p_pc_either"] = float(np.clip(pr["p_pc_either"], max(pr["p_pc_lh"], pr["p_pc_rh"]),
                                              min(1.0, pr["p_pc_lh"] + pr["p_pc_rh"])))
        report["passes"].append({"max_abs_error": round(worst, 4), "rows": rows})
        if worst < best[0]:  # a plan is a deterministic function of p': the best pass is the corpus
            best = (worst, probs)
        if worst <= float(cfg["calibration_tolerance"]):
            break
        probs = new
    report["chosen_pass"] = int(np.argmin([ps["max_abs_error"] for ps in report["passes"]]))
    probs = best[1]
    return probs, report
