"""Independent constraint checker: recomputes every constraint of a synthesized path from the
source (clip, frame) of each output frame and the database annotations (per-clip FrameAudio), as
runs of labels — a different code path from the per-frame masks the searches use."""
from __future__ import annotations

import numpy as np
import pandas as pd

from ..annotate.types import HP, IDLE, LR, PC


def _runs(labels: np.ndarray, code: int):
    d = np.diff(np.concatenate([[0], (labels == code).astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def check_path(source_clip, source_frame, clip_audio: dict, own_segments: pd.DataFrame,
               partner_segments: pd.DataFrame, fps: float, tolerance: float = 0.1, use_lr: bool = True,
               use_hp: bool = True) -> dict:
    """source_clip: (T,) clip names; source_frame: (T,) frames; clip_audio: name -> (own FrameAudio,
    partner FrameAudio) of the database clips. Returns {"total", "met", "details": [...]}: for every
    input PC (and LR, partner HP when enabled) whether a run of that label in the path's associated
    audio starts and ends within ``tolerance`` of it (PC: and has its source F0-peak frame within
    tolerance of the input peak), and whether the own label is idle wherever the input is idle."""
    T = len(source_frame)
    tol = tolerance * fps + 1e-9
    own = np.array([clip_audio[c][0].label[f] for c, f in zip(source_clip, source_frame)], np.int32)
    par = np.array([clip_audio[c][1].label[f] for c, f in zip(source_clip, source_frame)], np.int32)
    is_peak = np.array([clip_audio[c][0].seg_peak[f] == f and clip_audio[c][0].label[f] == PC
                        for c, f in zip(source_clip, source_frame)])
    details = []

    def seg_check(kind, code, labels, s, e, p=None):
        if max(0, s + tol) >= min(T, e - tol):  # its core lies outside the window: not a constraint
            return
        runs = [(a, b) for a, b in _runs(labels, code) if b > max(0, s) and a < min(T, e)]
        ok = False
        for a, b in runs:
            start_ok = s < 0 and a == 0 or abs(a - s) <= tol or (s - tol < 0 and a == 0)
            end_ok = e > T and b == T or abs(b - e) <= tol or (e + tol > T and b == T)
            peak_ok = True
            if p is not None and 0 <= p - tol and p + tol < T:
                lo, hi = int(np.ceil(p - tol)), int(np.floor(p + tol))
                peak_ok = bool(is_peak[lo:hi + 1].any())
            if start_ok and end_ok and peak_ok:
                ok = True
        details.append({"kind": kind, "start": s, "end": e, "peak": p, "met": ok})

    def fr(x):
        return int(round(x * fps))

    own_mask = np.zeros(T, bool)
    for r in own_segments.itertuples(index=False):
        s, e = fr(r.start), fr(r.end)
        own_mask[max(0, int(s - tol)):max(0, min(T, int(np.ceil(e + tol))))] = True
        if r.kind == "PC":
            seg_check("PC", PC, own, s, e, fr(r.peak) if np.isfinite(r.peak) else None)
        elif r.kind == "LR" and use_lr:
            seg_check("LR", LR, own, s, e)
    if use_hp and partner_segments is not None:
        for r in partner_segments.itertuples(index=False):
            if r.kind == "HP" and fr(r.end) > 0 and fr(r.start) < T:
                seg_check("PH", HP, par, fr(r.start), fr(r.end))
    idle = ~own_mask
    d = np.diff(np.concatenate([[0], idle.astype(np.int8), [0]]))
    for a, b in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)):
        details.append({"kind": "idle", "start": int(a), "end": int(b), "peak": None,
                        "met": bool(np.all(own[a:b] == IDLE))})
    met = sum(d["met"] for d in details)
    return {"total": len(details), "met": int(met), "details": details}
