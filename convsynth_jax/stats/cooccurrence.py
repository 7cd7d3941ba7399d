"""Audio-motion co-occurrence (paper Table 1) with tests against chance.

For each hypothesis (PC-LH, PC-RH, PC-LH/RH, LR-Nod, PH-Nod) an audio segment is *matched* when
the motion segmentation finds a movement of the hypothesis' kind in its candidate window (Figure 3).
Chance baseline: as many random windows of the same lengths (``stats.chance_windows`` per audio
window, default 1), placed elsewhere in the same clip (overlapping no audio segment of the channel the
hypothesis looks at, padded by half its length), get the same test with the same clip threshold θ_S;
the matched rates are compared with a chi-square test of independence (2x2, Yates-corrected, scipy)
and a one-sided permutation test (are audio windows matched more often than random ones?).
Random placement is seeded by the run's seed and the session and role (never display names), so tables are reproducible.
"""
from __future__ import annotations

import zlib

import numpy as np
import pandas as pd

from ..annotate.motion import (HYPOTHESIS_SPEC, Window, candidate_windows, detect_in_window, idle_threshold,
                               joint_speeds, segment_windows)
from ..annotate.params import AnnotateParams
from ..annotate.types import HYPOTHESES
from .params import StatsParams
from .tests import chi2_independence, permutation_test


def hypothesis_matches(speeds: dict, own: pd.DataFrame, partner: pd.DataFrame, fps: float, hypothesis: str,
                       alpha_s: float = 0.1, alpha_w: float = 0.1, extend_trim: bool = True):
    """(matched flags per audio segment, the candidate windows) for one hypothesis in one clip: the
    same windows and detections as ``segment_motion`` (LH/RH: a clause is matched if either hand moved)."""
    channel, akind, kinds = HYPOTHESIS_SPEC[hypothesis]
    segs = own if channel == "own" else partner
    if segs is None or len(segs) == 0:
        return np.zeros(0, bool), []
    sel = segs[segs["kind"] == akind]
    n = len(next(iter(speeds.values())))
    wins = candidate_windows(sel, n, fps, neighbours=segs)
    hit = np.zeros(len(wins), bool)
    for k in kinds:
        v = speeds[k]
        found = segment_windows(v, wins, idle_threshold(v, alpha_s), alpha_w, extend_trim=extend_trim)
        hit |= np.array([f is not None for f in found], bool)
    return hit, wins


def random_window_matches(speeds: dict, windows: list[Window], blocked: pd.DataFrame, fps: float, hypothesis: str,
                          rng: np.random.Generator, alpha_s: float = 0.1, alpha_w: float = 0.1,
                          per_window: int = 1) -> np.ndarray:
    """Matched flags of ``per_window`` random windows per window of ``windows`` (same length), placed
    where they overlap no segment of ``blocked`` (the channel's audio segments, padded by half their
    length). A window too long to fit anywhere is skipped (so the result may be shorter)."""
    _, _, kinds = HYPOTHESIS_SPEC[hypothesis]
    n = len(next(iter(speeds.values())))
    free = np.ones(n, bool)
    for s, e in zip(blocked["start"], blocked["end"]):
        pad = (e - s) / 2
        free[max(0, int((s - pad) * fps)): min(n, int(np.ceil((e + pad) * fps)))] = False
    cum = np.concatenate([[0], np.cumsum(~free)])
    thetas = {k: idle_threshold(speeds[k], alpha_s) for k in kinds}
    out = []
    for w in windows:
        L = max(1, w.end - w.start)
        starts = np.flatnonzero(cum[L:] - cum[:-L] == 0) if L <= n else np.zeros(0, int)
        if starts.size == 0:
            continue
        for a in rng.choice(starts, size=per_window):
            rw = Window(int(a), int(a) + L)
            out.append(any(detect_in_window(speeds[k], rw, thetas[k], alpha_w) is not None for k in kinds))
    return np.array(out, bool)


def clip_counts(ann, annotate: AnnotateParams, stats: StatsParams, seed: int = 0) -> pd.DataFrame:
    """Per hypothesis: matched/total in audio windows and in random windows, for one participant
    (a ParticipantAnnotation: its motion, own segments and partner segments are used). The match
    flags themselves are in the private columns ``_hits`` and ``_chance``."""
    alpha_s, alpha_w, extend = annotate.alpha_s, annotate.alpha_w, annotate.extend_trim
    per_window = int(stats.chance_windows)
    speeds = joint_speeds(ann.motion, annotate)
    fps = ann.motion.fps
    rng = np.random.default_rng([seed, zlib.crc32(f"{ann.session}/{ann.role}".encode())])
    rows = []
    for h in HYPOTHESES:
        hit, wins = hypothesis_matches(speeds, ann.segments, ann.partner_segments, fps, h, alpha_s, alpha_w, extend)
        channel = HYPOTHESIS_SPEC[h][0]
        blocked = ann.segments if channel == "own" else ann.partner_segments
        rnd = (random_window_matches(speeds, wins, blocked, fps, h, rng, alpha_s, alpha_w, per_window)
               if len(wins) else np.zeros(0, bool))
        rows.append({"session": ann.session, "role": ann.role, "character": ann.character, "hypothesis": h,
                     "matched": int(hit.sum()), "total": int(hit.size),
                     "chance_matched": int(rnd.sum()), "chance_total": int(rnd.size),
                     "_hits": hit, "_chance": rnd})
    return pd.DataFrame(rows)


TABLE_COLUMNS = ["character", "hypothesis", "matched", "total", "rate", "chance_matched", "chance_total",
                 "chance_rate", "chi2", "df", "p_chi2", "p_permutation"]


def _flatten(annotations) -> list:
    """A list of ParticipantAnnotation from a list, or from annotate_corpus' session -> role -> ann."""
    if isinstance(annotations, dict):
        annotations = list(annotations.values())
    out = []
    for a in annotations:
        out.extend(a.values() if isinstance(a, dict) else [a])
    return out


def cooccurrence_table(annotations, annotate: AnnotateParams, stats: StatsParams, seed: int = 0,
                       by_session: bool = False) -> pd.DataFrame:
    """Table 1 over ParticipantAnnotations (a list, or ``annotate_corpus`` output): one row per
    character x hypothesis (or per session x character x hypothesis with ``by_session``) with the
    columns TABLE_COLUMNS: matched, total, rate (0-1), the chance counts and rate in random windows,
    chi-square of independence (chi2, df, p_chi2) and the one-sided permutation p (p_permutation)."""
    annotations = _flatten(annotations)
    if not annotations:
        return pd.DataFrame(columns=(["session"] if by_session else []) + TABLE_COLUMNS)
    n_perm = int(stats.n_permutations)
    per_clip = pd.concat([clip_counts(a, annotate, stats, seed) for a in annotations], ignore_index=True)
    keys = ["session", "character", "hypothesis"] if by_session else ["character", "hypothesis"]
    rows = []
    for key, g in per_clip.groupby(keys, sort=False):
        hits = np.concatenate(list(g["_hits"])) if len(g) else np.zeros(0, bool)
        chance = np.concatenate(list(g["_chance"])) if len(g) else np.zeros(0, bool)
        m, t, cm, ct = int(hits.sum()), int(hits.size), int(chance.sum()), int(chance.size)
        ci = chi2_independence(m, t, cm, ct)
        row = dict(zip(keys, key if isinstance(key, tuple) else (key,)))
        row.update({"matched": m, "total": t, "rate": m / t if t else np.nan,
                    "chance_matched": cm, "chance_total": ct, "chance_rate": cm / ct if ct else np.nan,
                    "chi2": ci.chi2, "df": ci.df, "p_chi2": ci.p_value,
                    "p_permutation": permutation_test(hits, chance, n_perm, seed) if t and ct else np.nan})
        rows.append(row)
    out = pd.DataFrame(rows, columns=keys + TABLE_COLUMNS[2:])
    order = {h: i for i, h in enumerate(HYPOTHESES)}
    return out.sort_values(keys[:-1] + ["hypothesis"], key=lambda s: s.map(order) if s.name == "hypothesis" else s,
                           kind="stable").reset_index(drop=True)


def cooccurrence_by_session(annotations, annotate: AnnotateParams, stats: StatsParams, seed: int = 0) -> pd.DataFrame:
    """Per-session breakdown of Table 1: one row per session x character x hypothesis, same columns
    as ``cooccurrence_table`` plus ``session`` (tests per session have little power; read the rates)."""
    return cooccurrence_table(annotations, annotate, stats, seed, by_session=True)


def window_matches(events: pd.DataFrame, own: pd.DataFrame, partner: pd.DataFrame) -> dict:
    """hypothesis -> (matched, total) from already detected motion events (``segment_motion``
    output, whose ``segment`` column points at the audio segment whose window held the movement)."""
    out = {}
    for h, (channel, akind, kinds) in HYPOTHESIS_SPEC.items():
        segs = own if channel == "own" else partner
        total = int((segs["kind"] == akind).sum()) if segs is not None and len(segs) else 0
        if total == 0 or events is None or events.empty:
            out[h] = (0, total)
            continue
        ev = events[(events["channel"] == channel) & events["kind"].isin(kinds)]
        idx = set(ev["segment"].astype(int))
        sel = segs.index[segs["kind"] == akind]
        out[h] = (int(sum(i in idx for i in sel)), total)
    return out
