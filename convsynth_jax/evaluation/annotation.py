"""Scores of the annotation pipeline against a planted ground truth (the synthetic corpus's
``events.csv``): detected motion events and audio segments against the planted ones.

* :func:`overlap_counts`: a planted segment is found when a detected one overlaps it, a detected one
  is right when it overlaps a planted one (recall = found / planted, precision = right / detected).
* :func:`near`: for each time, whether another list holds one within a tolerance (clause boundaries).
* :func:`detection_scores`: motion events (LH, RH, Nod) per recording; recall over the movements the
  generator caused by audio, precision over every planted movement (spontaneous ones included).
* :func:`audio_scores`: clause boundaries (every start and end, matched within ``tolerance`` s),
  words per clause detected and planted, LR and HP by overlap.

``experiments/analysis/eval_annotation.py`` runs them on the default corpus with controls.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

CLAUSE_TOLERANCE_S = 0.15    # a planted clause boundary is matched by a detected one within this


def overlap_counts(planted: pd.DataFrame, detected: pd.DataFrame) -> tuple[int, int, int, int]:
    """(planted found, planted, detected right, detected) of two segment tables (start, end; s)."""
    hp = sum(bool(((detected["start"] < r.end) & (detected["end"] > r.start)).any()) for r in planted.itertuples())
    hd = sum(bool(((planted["start"] < r.end) & (planted["end"] > r.start)).any()) for r in detected.itertuples())
    return int(hp), len(planted), int(hd), len(detected)


def near(a, b, tolerance: float) -> np.ndarray:
    """(len(a),) bool: for each value of ``a``, is there a value of ``b`` within ``tolerance``."""
    a, b = np.asarray(a, float), np.sort(np.asarray(b, float))
    if not b.size:
        return np.zeros(a.size, bool)
    i = np.clip(np.searchsorted(b, a), 1, b.size) - 1
    j = np.clip(i + 1, 0, b.size - 1)
    return np.minimum(np.abs(a - b[i]), np.abs(a - b[j])) <= tolerance


def words_stats(n_words) -> dict:
    """Summary of words per clause: count, mean, sd, median, max, clauses over 15 words, histogram."""
    n = np.asarray(n_words, int)
    if not n.size:
        return {"clauses": 0}
    return {"clauses": int(n.size), "mean": float(n.mean()), "sd": float(n.std()), "median": float(np.median(n)),
            "max": int(n.max()), "over_15": int((n > 15).sum()),
            "histogram": {int(k): int(v) for k, v in zip(*np.unique(n, return_counts=True))}}


def detection_scores(ann: dict, events: pd.DataFrame, kinds=("LH", "RH", "Nod")) -> dict:
    """Motion-event detection against the planted events. ann: session -> role -> annotation with
    ``events`` (kind, start, end); events: the planted table (session, participant, kind, start,
    end, source; source "spontaneous" for movements no audio caused)."""
    per_kind = {}
    for s, parts in ann.items():
        for role, a in parts.items():
            pl = events[(events.session == s) & (events.participant == role)]
            caused = pl[pl.source != "spontaneous"]
            for k in kinds:
                d = a.events[a.events.kind == k].drop_duplicates(["start", "end"])
                hp, n_p, _, _ = overlap_counts(caused[caused.kind == k], d)
                _, _, hd, n_d = overlap_counts(pl[pl.kind == k], d)
                per_kind[k] = per_kind.get(k, np.zeros(4)) + (hp, n_p, hd, n_d)
    tot = sum(per_kind.values())
    return {"recall": tot[0] / max(tot[1], 1), "precision": tot[2] / max(tot[3], 1), "planted_caused": int(tot[1]),
            "detected": int(tot[3]),
            "per_kind": {k: {"recall": v[0] / max(v[1], 1), "precision": v[2] / max(v[3], 1)} for k, v in per_kind.items()}}


def audio_scores(ann: dict, events: pd.DataFrame, tolerance: float = CLAUSE_TOLERANCE_S) -> dict:
    """Clause boundary precision/recall (start and end of every clause, matched within ``tolerance``),
    words per clause detected vs planted, LR/HP overlap precision/recall. ann: session -> role ->
    annotation with ``segments`` (kind, start, end, text); events: the planted PC/LR/HP rows."""
    hits = {k: np.zeros(4) for k in ("PC", "LR", "HP")}
    det_words, pl_words = [], []
    for s, parts in ann.items():
        for role, a in parts.items():
            pl = events[(events.session == s) & (events.participant == role)]
            seg = a.segments
            p_pc, d_pc = pl[pl.kind == "PC"], seg[seg.kind == "PC"]
            pb = np.concatenate([p_pc.start, p_pc.end])
            db = np.concatenate([d_pc.start, d_pc.end])
            hits["PC"] += (near(pb, db, tolerance).sum(), pb.size, near(db, pb, tolerance).sum(), db.size)
            det_words += d_pc.text.str.split().str.len().tolist()
            pl_words += p_pc.text.str.split().str.len().tolist()
            for k in ("LR", "HP"):
                hits[k] += overlap_counts(pl[pl.kind == k], seg[seg.kind == k])
    out = {k: {"recall": v[0] / max(v[1], 1), "precision": v[2] / max(v[3], 1), "planted": int(v[1]),
               "detected": int(v[3])} for k, v in hits.items()}
    out["PC"]["tolerance_s"] = tolerance
    out["words_per_clause"] = {"detected": words_stats(det_words), "planted": words_stats(pl_words)}
    return out
