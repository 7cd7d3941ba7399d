"""Audio-motion co-occurrence (paper Table 1) with tests against chance.

For each hypothesis (PC-LH, PC-RH, PC-LH/RH, LR-Nod, PH-Nod) an audio segment is *matched* when
the motion segmentation finds a movement of the hypothesis' kind in its candidate window (Figure 3).
``hypothesis_matches`` is the one counting function: Table 1, its chance windows, and the ground-truth
and synthesized windows of the leave-one-out evaluation all call it with Eq. 1's idle thresholds θ_S
precomputed per recording (``annotate.motion.recording_thresholds``; synthesized motion: the mean of
the character's training recordings, ``character_thresholds``), never over the window at hand.

Chance baseline (``StatsParams.chance_baseline``): ``away`` = as many random windows of the same
lengths (``stats.chance_windows`` per audio window, default 1), placed elsewhere in the same clip
(overlapping no audio segment of the channel the hypothesis looks at, padded by half its length);
``shifted`` (ours) = each audio window moved to a random time of the same recording where it does not
overlap itself. When the baseline places no window for a row (continuous speech leaves no room away
from the segments), ``StatsParams.chance_fallback`` decides: ``shifted`` (ours, default) uses shifted
windows for that row, ``none`` reports no baseline (empty p-values, a logged warning). The column
``chance_method`` says which baseline each row used. Chance windows get the same test with the same
recording θ_S; the matched rates are compared with a chi-square test of independence (2x2,
Yates-corrected, scipy) and a one-sided permutation test (are audio windows matched more often than
random ones?); rates carry Wilson confidence intervals (``stats.confidence``, default 95%).
Random placement is seeded by the run's seed and the session and role (never display names), so
tables are reproducible.
"""
from __future__ import annotations

import logging
import zlib

import numpy as np
import pandas as pd

from ..annotate.motion import (HYPOTHESIS_SPEC, FrameWindow, candidate_windows, check_thresholds, detect_in_window,
                               joint_speeds, recording_thresholds, segment_windows)
from ..annotate.params import AnnotateParams
from ..annotate.types import HYPOTHESES
from .params import StatsParams
from .hypothesis import chi2_independence, permutation_test, wilson_interval

log = logging.getLogger(__name__)


def hypothesis_matches(speeds: dict, own: pd.DataFrame, partner: pd.DataFrame, fps: float, hypothesis: str, *,
                       thresholds: dict, alpha_w: float = 0.1, extend_trim: bool = True):
    """(matched flags per audio segment, the candidate windows) for one hypothesis in one clip or
    window: the same windows and detections as ``segment_motion`` (LH/RH: a clause is matched if
    either hand moved).

    speeds: ``joint_speeds`` output of the motion judged ((F,) per kind; a whole recording or a
    window of one); own / partner: DataFrame[kind, start, end] in seconds relative to frame 0 of
    ``speeds`` (segments may cross its edges; their candidate windows are clipped to it);
    thresholds: Eq. 1's θ_S per kind of the *recording* (``recording_thresholds`` over the whole
    clip, or ``character_thresholds`` for synthesized motion), required so no caller can fall back
    to a threshold over the window."""
    channel, akind, kinds = HYPOTHESIS_SPEC[hypothesis]
    check_thresholds(thresholds, kinds, where=f"hypothesis_matches({hypothesis})")
    segs = own if channel == "own" else partner
    if segs is None or len(segs) == 0:
        return np.zeros(0, bool), []
    sel = segs[segs["kind"] == akind]
    n = len(next(iter(speeds.values())))
    wins = candidate_windows(sel, n, fps, neighbours=segs)
    hit = np.zeros(len(wins), bool)
    for k in kinds:
        found = segment_windows(speeds[k], wins, float(thresholds[k]), alpha_w, extend_trim=extend_trim)
        hit |= np.array([f is not None for f in found], bool)
    return hit, wins


def matches_by_hypothesis(speeds: dict, own: pd.DataFrame, partner: pd.DataFrame, fps: float, thresholds: dict,
                          annotate: AnnotateParams) -> dict:
    """hypothesis -> matched flags per audio segment (``hypothesis_matches`` for every hypothesis)."""
    return {h: hypothesis_matches(speeds, own, partner, fps, h, thresholds=thresholds, alpha_w=annotate.alpha_w,
                                  extend_trim=annotate.extend_trim)[0] for h in HYPOTHESES}


def window_counts(speeds: dict, own: pd.DataFrame, partner: pd.DataFrame, fps: float, thresholds: dict,
                  annotate: AnnotateParams) -> dict:
    """hypothesis -> (matched, total) in one window of motion (``speeds``), by ``hypothesis_matches``
    with the given recording thresholds (the leave-one-out ground truth and synthesized windows)."""
    return {h: (int(f.sum()), int(f.size))
            for h, f in matches_by_hypothesis(speeds, own, partner, fps, thresholds, annotate).items()}


def away_windows(num_frames: int, windows: list[FrameWindow], blocked: pd.DataFrame, fps: float, rng: np.random.Generator,
                 per_window: int = 1) -> list[FrameWindow]:
    """``per_window`` random windows per window of ``windows`` (same length), placed where they
    overlap no segment of ``blocked`` (the channel's audio segments, padded by half their length).
    A window too long to fit anywhere is skipped (so the result may be shorter, or empty)."""
    n = num_frames
    free = np.ones(n, bool)
    for s, e in zip(blocked["start"], blocked["end"]):
        pad = (e - s) / 2
        free[max(0, int((s - pad) * fps)): min(n, int(np.ceil((e + pad) * fps)))] = False
    cum = np.concatenate([[0], np.cumsum(~free)])
    out = []
    for w in windows:
        L = max(1, w.end - w.start)
        starts = np.flatnonzero(cum[L:] - cum[:-L] == 0) if L <= n else np.zeros(0, int)
        if starts.size == 0:
            continue
        out.extend(FrameWindow(int(a), int(a) + L) for a in rng.choice(starts, size=per_window))
    return out


def shifted_windows(num_frames: int, windows: list[FrameWindow], rng: np.random.Generator,
                    per_window: int = 1) -> list[FrameWindow]:
    """Ours: ``per_window`` copies of each window moved to a random start of the same recording where
    the copy does not overlap the original (|shift| >= its length); speech may lie there, so this
    baseline exists for continuous speech. A window with no such place (the clip is shorter than
    twice its length) is skipped."""
    out = []
    for w in windows:
        L = max(1, w.end - w.start)
        starts = np.arange(max(0, num_frames - L + 1))
        starts = starts[np.abs(starts - w.start) >= L]
        if starts.size == 0:
            continue
        out.extend(FrameWindow(int(a), int(a) + L) for a in rng.choice(starts, size=per_window))
    return out


def chance_matches(speeds: dict, windows: list[FrameWindow], hypothesis: str, thresholds: dict,
                   alpha_w: float = 0.1) -> np.ndarray:
    """Matched flags of chance windows: a movement of the hypothesis' kind above the recording's θ_S
    (Eq. 1) in the window, bounded by Eq. 2 (``detect_in_window``, as in ``hypothesis_matches``, but
    without trimming against earlier windows: random windows are not a sequence)."""
    _, _, kinds = HYPOTHESIS_SPEC[hypothesis]
    check_thresholds(thresholds, kinds, where=f"chance_matches({hypothesis})")
    return np.array([any(detect_in_window(speeds[k], w, float(thresholds[k]), alpha_w) is not None for k in kinds)
                     for w in windows], bool)


def random_window_matches(speeds: dict, windows: list[FrameWindow], blocked: pd.DataFrame, fps: float, hypothesis: str,
                          rng: np.random.Generator, thresholds: dict, alpha_w: float = 0.1,
                          per_window: int = 1) -> np.ndarray:
    """Matched flags of the ``away`` chance windows (``away_windows`` then ``chance_matches``)."""
    n = len(next(iter(speeds.values())))
    return chance_matches(speeds, away_windows(n, windows, blocked, fps, rng, per_window), hypothesis, thresholds,
                          alpha_w)


def clip_counts(ann, annotate: AnnotateParams, stats: StatsParams, seed: int = 0,
                thresholds: dict | None = None) -> pd.DataFrame:
    """Per hypothesis: matched/total in audio windows and in chance windows of both kinds, for one
    participant (a ParticipantAnnotation: its motion, own segments and partner segments are used).
    ``thresholds``: Eq. 1's θ_S per kind of this recording (default: over its whole clip). The match
    flags themselves are in the private columns ``_hits``, ``_away`` and ``_shifted``."""
    alpha_w = annotate.alpha_w
    per_window = int(stats.chance_windows)
    speeds = joint_speeds(ann.motion, annotate)
    thresholds = recording_thresholds(speeds, annotate.alpha_s) if thresholds is None else thresholds
    fps = ann.motion.fps
    n = ann.motion.num_frames
    key = zlib.crc32(f"{ann.session}/{ann.role}".encode())
    rng = np.random.default_rng([seed, key])
    rng_shift = np.random.default_rng([seed, key, 1])  # its own stream: the away windows stay as they were
    rows = []
    for h in HYPOTHESES:
        hit, wins = hypothesis_matches(speeds, ann.segments, ann.partner_segments, fps, h, thresholds=thresholds,
                                       alpha_w=alpha_w, extend_trim=annotate.extend_trim)
        channel = HYPOTHESIS_SPEC[h][0]
        blocked = ann.segments if channel == "own" else ann.partner_segments
        away = chance_matches(speeds, away_windows(n, wins, blocked, fps, rng, per_window), h, thresholds, alpha_w)
        shifted = chance_matches(speeds, shifted_windows(n, wins, rng_shift, per_window), h, thresholds, alpha_w)
        rows.append({"session": ann.session, "role": ann.role, "character": ann.character, "hypothesis": h,
                     "matched": int(hit.sum()), "total": int(hit.size),
                     "away_matched": int(away.sum()), "away_total": int(away.size),
                     "shifted_matched": int(shifted.sum()), "shifted_total": int(shifted.size),
                     "_hits": hit, "_away": away, "_shifted": shifted})
    return pd.DataFrame(rows)


TABLE_COLUMNS = ["character", "hypothesis", "matched", "total", "rate", "ci_low", "ci_high", "chance_method",
                 "chance_matched", "chance_total", "chance_rate", "chance_ci_low", "chance_ci_high", "chi2", "df",
                 "p_chi2", "p_permutation"]


def _flatten(annotations) -> list:
    """A list of ParticipantAnnotation from a list, or from annotate_corpus' session -> role -> ann."""
    if isinstance(annotations, dict):
        annotations = list(annotations.values())
    out = []
    for a in annotations:
        out.extend(a.values() if isinstance(a, dict) else [a])
    return out


def choose_baseline(away_total: int, shifted_total: int, stats: StatsParams) -> str:
    """The chance baseline a row uses: ``stats.chance_baseline`` when it placed a window; else the
    fallback (``shifted`` when that placed one); else ``none``."""
    primary = str(stats.chance_baseline)
    totals = {"away": away_total, "shifted": shifted_total}
    if totals[primary] > 0:
        return primary
    if stats.chance_fallback == "shifted" and shifted_total > 0:
        return "shifted"
    return "none"


def cooccurrence_table(annotations, annotate: AnnotateParams, stats: StatsParams, seed: int = 0,
                       by_session: bool = False, thresholds: dict | None = None) -> pd.DataFrame:
    """Table 1 over ParticipantAnnotations (a list, or ``annotate_corpus`` output): one row per
    character x hypothesis (or per session x character x hypothesis with ``by_session``) with the
    columns TABLE_COLUMNS: matched, total, rate (0-1) with its Wilson interval (ci_low, ci_high at
    ``stats.confidence``), the chance baseline used (chance_method: away | shifted | none), the
    chance counts, rate and interval, chi-square of independence (chi2, df, p_chi2) and the one-sided
    permutation p (p_permutation); without a baseline (``none``) the chance columns and p-values are
    empty and a warning is logged. ``thresholds``: optional (session, role) -> {kind: θ_S}; default
    Eq. 1 over each participant's whole clip."""
    annotations = _flatten(annotations)
    if not annotations:
        return pd.DataFrame(columns=(["session"] if by_session else []) + TABLE_COLUMNS)
    n_perm = int(stats.n_permutations)
    conf = float(stats.confidence)
    per_clip = pd.concat([clip_counts(a, annotate, stats, seed, (thresholds or {}).get((a.session, a.role)))
                          for a in annotations], ignore_index=True)
    keys = ["session", "character", "hypothesis"] if by_session else ["character", "hypothesis"]
    rows = []
    for key, g in per_clip.groupby(keys, sort=False):
        hits = np.concatenate(list(g["_hits"]))
        m, t = int(hits.sum()), int(hits.size)
        method = choose_baseline(int(g["away_total"].sum()), int(g["shifted_total"].sum()), stats) if t else "none"
        row = dict(zip(keys, key if isinstance(key, tuple) else (key,)))
        lo, hi = wilson_interval(m, t, conf)
        row.update({"matched": m, "total": t, "rate": m / t if t else np.nan, "ci_low": lo, "ci_high": hi,
                    "chance_method": method})
        if method == "none":
            if t:
                log.warning("no chance baseline for %s: no %s window fits (stats.chance_fallback=%s); p-values left "
                            "empty", " ".join(map(str, key)) if isinstance(key, tuple) else key,
                            stats.chance_baseline, stats.chance_fallback)
            row.update({"chance_matched": np.nan, "chance_total": 0, "chance_rate": np.nan, "chance_ci_low": np.nan,
                        "chance_ci_high": np.nan, "chi2": np.nan, "df": np.nan, "p_chi2": np.nan,
                        "p_permutation": np.nan})
            rows.append(row)
            continue
        if method != stats.chance_baseline:
            log.warning("chance baseline for %s: no %s window fits; using %s windows instead",
                        " ".join(map(str, key)) if isinstance(key, tuple) else key, stats.chance_baseline, method)
        chance = np.concatenate(list(g[f"_{method}"]))
        cm, ct = int(chance.sum()), int(chance.size)
        ci = chi2_independence(m, t, cm, ct)
        clo, chi = wilson_interval(cm, ct, conf)
        row.update({"chance_matched": cm, "chance_total": ct, "chance_rate": cm / ct, "chance_ci_low": clo,
                    "chance_ci_high": chi, "chi2": ci.chi2, "df": ci.df, "p_chi2": ci.p_value,
                    "p_permutation": permutation_test(hits, chance, n_perm, seed)})
        rows.append(row)
    out = pd.DataFrame(rows, columns=keys + TABLE_COLUMNS[2:])
    order = {h: i for i, h in enumerate(HYPOTHESES)}
    return out.sort_values(keys[:-1] + ["hypothesis"], key=lambda s: s.map(order) if s.name == "hypothesis" else s,
                           kind="stable").reset_index(drop=True)


def cooccurrence_by_session(annotations, annotate: AnnotateParams, stats: StatsParams, seed: int = 0) -> pd.DataFrame:
    """Per-session breakdown of Table 1: one row per session x character x hypothesis, same columns
    as ``cooccurrence_table`` plus ``session`` (tests per session have little power; read the rates)."""
    return cooccurrence_table(annotations, annotate, stats, seed, by_session=True)
