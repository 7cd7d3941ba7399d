"""Consistency of the co-occurrence measure between Table 1 and the leave-one-out windows.

Table 1 counts each audio segment of a recording once, over the whole clip. The leave-one-out
evaluation counts the ground truth of the same recordings window by window (15 s windows, 14 s hop,
over every fold's held-out session). Both use one function (``stats.cooccurrence.hypothesis_matches``)
with Eq. 1's idle threshold of the recording, so summed over all windows the leave-one-out ground truth
must reproduce Table 1 up to what cutting the recording into windows explains:

* totals: consecutive windows overlap (15 s windows, 14 s hop), so a segment overlapping k windows
  is counted k times: total_loo - total_table1 = duplicated - uncovered exactly, where
  ``duplicated`` sums k - 1 over the segments with k >= 2 and ``uncovered`` counts the segments no
  window overlaps (the tail of a session after its last window);
* matched: a segment's detection can only change where its candidate window (the segment expanded to
  twice its length, Figure 3) is clipped by a window edge, where it is counted again, or where no
  window covers it, so |matched_loo - matched_table1| <= edge_affected + duplicated + uncovered
  (``edge_affected`` counts (segment, window) pairs whose candidate window reaches past a window edge;
  it includes the ``straddling`` pairs, whose segment itself crosses the edge);
* and the summed leave-one-out rate lies inside Table 1's Wilson interval (``stats.confidence``).

A row passes when all three hold. ``threshold_scope="window"`` recomputes Eq. 1 over each window,
the per-window threshold that broke the agreement (kept only as the negative control that the check must reject).
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from ..annotate.motion import HYPOTHESIS_SPEC, joint_speeds, recording_thresholds
from ..annotate.types import HYPOTHESES
from ..errors import ConfigError
from ..stats.hypothesis import wilson_interval
from .loo import recording_threshold_table, session_windows, window_cooccurrence, window_input

THRESHOLD_SCOPES = ("recording", "window")


def _edge_counts(segs: pd.DataFrame, akind: str, duration: float) -> tuple[int, int]:
    """(straddling, edge_affected) segments of kind ``akind`` among window-relative ``segs``."""
    if segs is None or len(segs) == 0:
        return 0, 0
    sel = segs[segs["kind"] == akind]
    s, e = np.asarray(sel["start"], float), np.asarray(sel["end"], float)
    half = (e - s) / 2
    straddle = (s < 0) | (e > duration)
    edge = straddle | (s - half < 0) | (e + half > duration)
    return int(straddle.sum()), int(edge.sum())


def loo_ground_truth(annotations: dict, params, threshold_scope: str = "recording") -> pd.DataFrame:
    """Ground-truth co-occurrence of every leave-one-out window of every fold, counted as
    ``run_fold`` counts it (``window_input`` + ``window_cooccurrence`` with the held-out recording's
    thresholds), without synthesizing anything: one row per (fold, window, role) with
    ``gt_<h>_matched`` / ``gt_<h>_total`` and ``straddling_<h>`` / ``edge_affected_<h>``, plus one row
    per recording with window = -1 holding ``uncovered_<h>`` (segments no window overlaps) and
    ``duplicated_<h>`` (extra counts of segments that several windows overlap)."""
    if threshold_scope not in THRESHOLD_SCOPES:
        raise ConfigError(f"unknown threshold scope {threshold_scope!r}; expected one of {THRESHOLD_SCOPES}")
    ap = params.annotate
    fps = float(params.features.fps)
    table = recording_threshold_table(annotations, ap) if threshold_scope == "recording" else {}
    rows = []
    for fold, (session, held) in enumerate(annotations.items()):
        windows = session_windows(held, fps, params.loo.window, params.loo.hop, params.loo.max_windows)
        for role, ann in held.items():
            covered = {h: np.zeros(0, int) for h in HYPOTHESES}
            for h, (channel, akind, _) in HYPOTHESIS_SPEC.items():
                segs = ann.segments if channel == "own" else ann.partner_segments
                sel = segs[segs["kind"] == akind] if segs is not None and len(segs) else segs
                n = 0 if sel is None else len(sel)
                cov = np.zeros(n, int)
                for w in windows:  # the selection of ``window_segments``
                    if n:
                        cov += np.asarray((sel["end"] > w.start) & (sel["start"] < w.end), int)
                covered[h] = cov
            rows.append({"fold": fold, "session": session, "window": -1, "role": role, "character": ann.character,
                         **{f"uncovered_{h}": int((c == 0).sum()) for h, c in covered.items()},
                         **{f"duplicated_{h}": int(np.maximum(c - 1, 0).sum()) for h, c in covered.items()}})
            for w in windows:
                win = window_input(held, role, w, fps, 0)
                gt = ann.motion.slice(win.start_frame, win.start_frame + win.num_frames)
                if threshold_scope == "recording":
                    th = table[(session, role)]
                else:  # the old defect: Eq. 1 over the window itself
                    th = recording_thresholds(joint_speeds(gt, ap), ap.alpha_s)
                row = {"fold": fold, "session": session, "window": w.index, "role": role,
                       "character": ann.character}
                row.update(window_cooccurrence(gt, win.own_segments, win.partner_segments, th, params, "gt"))
                for h, (channel, akind, _) in HYPOTHESIS_SPEC.items():
                    segs = win.own_segments if channel == "own" else win.partner_segments
                    row[f"straddling_{h}"], row[f"edge_affected_{h}"] = _edge_counts(segs, akind, w.duration)
                rows.append(row)
    return pd.DataFrame(rows)


CONSISTENCY_COLUMNS = ["character", "hypothesis", "table1_matched", "table1_total", "table1_rate", "ci_low", "ci_high",
                       "loo_matched", "loo_total", "loo_rate", "diff_matched", "diff_total", "straddling",
                       "edge_affected", "duplicated", "uncovered", "within_edges", "within_ci", "passes"]


def consistency_table(table1: pd.DataFrame, gt: pd.DataFrame, edges: pd.DataFrame | None = None,
                      confidence: float = 0.95) -> pd.DataFrame:
    """One row per character x hypothesis of ``table1`` (``cooccurrence_table`` output): Table 1's
    counts and Wilson interval beside the leave-one-out ground truth summed over ``gt`` (rows with
    character and ``gt_<h>_matched`` / ``_total``: ``loo_ground_truth`` output, or the test cases of
    ``run_fold`` over every fold of one condition), the differences, the edge allowances (from
    ``edges``, a ``loo_ground_truth`` output; default ``gt``) and the verdicts (CONSISTENCY_COLUMNS;
    see the module docstring for the rule)."""
    edges = gt if edges is None else edges
    rows = []
    for r in table1.itertuples(index=False):
        g = gt[gt["character"] == r.character]
        e = edges[edges["character"] == r.character]
        h = r.hypothesis
        lm, lt = int(g[f"gt_{h}_matched"].sum()), int(g[f"gt_{h}_total"].sum())
        straddling = int(e[f"straddling_{h}"].sum())
        edge = int(e[f"edge_affected_{h}"].sum())
        uncovered = int(e[f"uncovered_{h}"].sum())
        duplicated = int(e[f"duplicated_{h}"].sum())
        tm, tt = int(r.matched), int(r.total)
        lo, hi = wilson_interval(tm, tt, confidence)
        loo_rate = lm / lt if lt else np.nan
        within_edges = lt - tt == duplicated - uncovered and abs(lm - tm) <= edge + duplicated + uncovered
        within_ci = bool(lt == 0 and tt == 0) or (lt > 0 and tt > 0 and lo - 1e-12 <= loo_rate <= hi + 1e-12)
        rows.append({"character": r.character, "hypothesis": h, "table1_matched": tm, "table1_total": tt,
                     "table1_rate": tm / tt if tt else np.nan, "ci_low": lo, "ci_high": hi,
                     "loo_matched": lm, "loo_total": lt, "loo_rate": loo_rate, "diff_matched": lm - tm,
                     "diff_total": lt - tt, "straddling": straddling, "edge_affected": edge, "duplicated": duplicated,
                     "uncovered": uncovered,
                     "within_edges": bool(within_edges), "within_ci": bool(within_ci),
                     "passes": bool(within_edges and within_ci)})
    return pd.DataFrame(rows, columns=CONSISTENCY_COLUMNS)


def check_consistency(annotations: dict, params, table1: pd.DataFrame | None = None,
                      threshold_scope: str = "recording") -> pd.DataFrame:
    """``consistency_table`` of Table 1 (computed here unless given) against the leave-one-out
    ground truth of ``annotations`` (session -> role -> ParticipantAnnotation)."""
    if table1 is None:
        from ..stats.cooccurrence import cooccurrence_table

        table1 = cooccurrence_table(annotations, params.annotate, params.stats, params.seed)
    gt = loo_ground_truth(annotations, params, threshold_scope)
    return consistency_table(table1, gt, confidence=float(params.stats.confidence))
