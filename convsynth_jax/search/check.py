"""Independent constraint checker: recomputes every constraint of a synthesized path from the
source (clip, frame) of each output frame and the database annotations (per-clip FrameAudio) — a
different code path from the per-frame masks and entry windows the searches use.

``matching="labels"`` (ours, relaxed) checks runs of labels in the path's associated audio.
``matching="paper"`` checks the paper's rule: the path's source frames are cut into *instances*
(maximal runs of consecutive frames of one clip inside one annotated source segment); an instance
is whole when it starts at its segment's first frame (or at output frame 0) and ends at its last
(or at the window's end), and it places its segment on the output timeline (start, end and F0
peak); each input segment must be matched, one to one, by a whole instance of its kind placed
within the tolerance.

The kinds checked (their channels, labels, peaks and switches) are the registry's
(:mod:`convsynth_jax.annotate.kinds`); ``use_lr`` / ``use_hp`` (and ``switches``, for a registered
kind's own switch) turn kinds off.

Idle runs are the frames outside every own input segment widened by the tolerance on both sides,
[s - tol, e + tol) with tol in whole frames, as the searches build them.

Retiming (ours): ``warp`` = (output knots, path knots) of ``search/retime.py``. Output frame t then
shows the path at time np.interp(t, out_knots, path_knots); instances are placed by mapping their
start, end and peak from the path's timeline to the output's (the inverse map), and the idle rule
reads the label of the path frame nearest to each output frame's path time.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from ..annotate.kinds import IDLE, kind_of_segment, segment_kinds
from ..annotate.types import FrameAudio
from ..errors import ConfigError


def _runs(labels: np.ndarray, code: int):
    d = np.diff(np.concatenate([[0], (labels == code).astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def _instances(source_clip, source_frame, fa_of, code) -> list[dict]:
    """Whole-or-cut played instances of source segments labelled ``code`` (fa_of(clip) -> FrameAudio):
    dicts with output frames [u, v), placement start/end/peak on the output timeline, whole flag."""
    T = len(source_frame)
    out, cur = [], None
    for t in range(T):
        c, f = source_clip[t], int(source_frame[t])
        fa = fa_of(c)
        a = int(fa.seg_start[f])
        if int(fa.label[f]) != code or a < 0:
            cur = None
            continue
        if cur is not None and cur["clip"] == c and cur["a"] == a and f == cur["last"] + 1:
            cur["last"], cur["v"] = f, t + 1
            continue
        b, pk = int(fa.seg_end[f]), int(fa.seg_peak[f])
        cur = {"clip": c, "a": a, "b": b, "first": f, "last": f, "u": t, "v": t + 1, "peak_src": pk}
        out.append(cur)
    for x in out:
        st = x["u"] - (x["first"] - x["a"])
        x["whole"] = (x["first"] == x["a"] or x["u"] == 0) and (x["last"] == x["b"] - 1 or x["v"] == T)
        x["start"], x["end"] = st, st + x["b"] - x["a"]
        x["peak"] = st + x["peak_src"] - x["a"] if x["peak_src"] >= 0 else None
    return out


def _idle_range(s, e, tolerance, fps, T):
    """The output frames [lo, hi) an own input segment [s, e) (frames) frees from the idle rule."""
    k = int(round(tolerance * fps))
    return max(0, s - k), max(0, min(T, e + k))


def _to_output(warp, T):
    """Map from the path's timeline to the output's (identity without a warp or outside [0, T - 1])."""
    if warp is None:
        return lambda x: x
    out_k, path_k = (np.asarray(k, np.float64) for k in warp)

    def f(x):
        if x is None or x <= 0 or x >= T - 1:
            return x
        return float(np.interp(x, path_k, out_k))
    return f


def _check_paper(source_clip, source_frame, clip_audio, own_segments, partner_segments, fps, tolerance,
                 switches, warp=None) -> dict:
    T = len(source_frame)
    tol = tolerance * fps + 1e-9
    details = []
    to_out = _to_output(warp, T)

    def fr(x):
        return int(round(x * fps))

    def counted(s, e):
        return 0 <= s + tol < T or (s + tol < 0 and min(T, e - tol) > 0)

    def match(kind, code, channel, segs):
        inst = [x for x in _instances(source_clip, source_frame, lambda c: clip_audio[c][channel], code)
                if x["whole"]]
        for x in inst:
            x["start"], x["end"], x["peak"] = to_out(x["start"]), to_out(x["end"]), to_out(x["peak"])
        used = set()
        for s, e, p in sorted(segs):
            if not counted(s, e):
                continue
            ok = False
            for i, x in enumerate(inst):
                if i in used or abs(x["start"] - s) > tol or abs(x["end"] - e) > tol:
                    continue
                if p is not None and (x["peak"] is None or abs(x["peak"] - p) > tol):
                    continue
                used.add(i)
                ok = True
                break
            details.append({"kind": kind, "start": s, "end": e, "peak": p, "met": ok})

    own_mask = np.zeros(T, bool)
    kinds = [k for k in segment_kinds() if k.enabled(switches)]
    inputs = {k.name: [] for k in kinds}
    for r in own_segments.itertuples(index=False):
        s, e = fr(r.start), fr(r.end)
        lo, hi = _idle_range(s, e, tolerance, fps, T)
        own_mask[lo:hi] = True
        k = kind_of_segment("own", r.kind)
        if k is not None and k.name in inputs:
            inputs[k.name].append((s, e, fr(r.peak) if k.has_peak and np.isfinite(r.peak) else None))
    for r in (partner_segments.itertuples(index=False) if partner_segments is not None else ()):
        k = kind_of_segment("partner", r.kind)
        if k is not None and k.name in inputs:
            inputs[k.name].append((fr(r.start), fr(r.end), None))
    for k in kinds:
        if k.channel == "own" or partner_segments is not None:
            match(k.name, k.code, 0 if k.channel == "own" else 1, inputs[k.name])
    own = np.array([clip_audio[c][0].label[f] for c, f in zip(source_clip, source_frame)], np.int32)
    if warp is not None:
        # the label shown at each output frame: that of the path frame its path time lies in, floor(tau), so
        # that a played instance [st, en) of the path shows on exactly the output frames [to_out(st),
        # to_out(en)) its placement is read at above (the nearest frame would show a clause whose start the
        # warp puts at s from up to half a path frame earlier: several output frames where a short pause
        # is stretched)
        tau = np.interp(np.arange(T), *(np.asarray(k, np.float64) for k in warp))
        own = own[np.clip(np.floor(tau + 1e-9).astype(np.int64), 0, T - 1)]
    d = np.diff(np.concatenate([[0], (~own_mask).astype(np.int8), [0]]))
    for a, b in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)):
        details.append({"kind": "idle", "start": int(a), "end": int(b), "peak": None,
                        "met": bool(np.all(own[a:b] == IDLE))})
    return {"total": len(details), "met": int(sum(x["met"] for x in details)), "details": details}


def check_path(source_clip, source_frame, clip_audio: dict, own_segments: pd.DataFrame,
               partner_segments: pd.DataFrame, fps: float, tolerance: float = 0.1, use_lr: bool = True,
               use_hp: bool = True, matching: str = "paper", warp=None, switches=None) -> dict:
    """source_clip: (T,) clip names; source_frame: (T,) frames; clip_audio: name -> (own FrameAudio,
    partner FrameAudio) of the database clips. Returns {"total", "met", "details": [...]}: for every
    input PC (and LR, partner HP when enabled) whether a run of that label in the path's associated
    audio starts and ends within ``tolerance`` of it (PC: and has its source F0-peak frame within
    tolerance of the input peak), and whether the own label is idle wherever the input is idle
    (``matching="labels"``); ``matching="paper"``: see the module docstring. ``warp``: the retiming
    warp (``paper`` only; module docstring). ``switches``: switch name -> bool for registered kinds'
    switches (``use_lr`` / ``use_hp`` win over it for theirs; a switch named nowhere is on)."""
    own_segments = own_segments if own_segments is not None else pd.DataFrame(columns=["kind", "start", "end", "peak"])
    switches = {**(switches or {}), "use_lr": bool(use_lr), "use_hp": bool(use_hp)}
    if matching == "paper":
        return _check_paper(source_clip, source_frame, clip_audio, own_segments, partner_segments, fps, tolerance,
                            switches, warp)
    if matching != "labels":
        raise ConfigError(f"matching must be 'paper' or 'labels', got {matching!r}")
    if warp is not None:
        raise ConfigError("a retiming warp can only be checked with matching='paper'")
    T = len(source_frame)
    tol = tolerance * fps + 1e-9
    own = np.array([clip_audio[c][0].label[f] for c, f in zip(source_clip, source_frame)], np.int32)
    par = np.array([clip_audio[c][1].label[f] for c, f in zip(source_clip, source_frame)], np.int32)
    peaked = {k.code for k in segment_kinds("own") if k.has_peak}
    is_peak = np.array([clip_audio[c][0].seg_peak[f] == f and int(clip_audio[c][0].label[f]) in peaked
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
        lo, hi = _idle_range(s, e, tolerance, fps, T)
        own_mask[lo:hi] = True
        k = kind_of_segment("own", r.kind)
        if k is not None and k.enabled(switches):
            seg_check(k.name, k.code, own, s, e, fr(r.peak) if k.has_peak and np.isfinite(r.peak) else None)
    if partner_segments is not None:
        for r in partner_segments.itertuples(index=False):
            k = kind_of_segment("partner", r.kind)
            if k is not None and k.enabled(switches) and fr(r.end) > 0 and fr(r.start) < T:
                seg_check(k.name, k.code, par, fr(r.start), fr(r.end))
    idle = ~own_mask
    d = np.diff(np.concatenate([[0], idle.astype(np.int8), [0]]))
    for a, b in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)):
        details.append({"kind": "idle", "start": int(a), "end": int(b), "peak": None,
                        "met": bool(np.all(own[a:b] == IDLE))})
    met = sum(d["met"] for d in details)
    return {"total": len(details), "met": int(met), "details": details}


def clip_audio_of_graph(graph) -> dict:
    """clip name -> (own FrameAudio, partner FrameAudio) of the source frames a graph stores (frames
    without a state: idle), for :func:`check_path` where the database annotation is not at hand."""
    out = {}
    for c, name in enumerate(graph.clip_names):
        idx = np.flatnonzero(graph.clip == c)
        n = int(graph.frame[idx].max()) + 1 if idx.size else 0
        f = graph.frame[idx]

        def fa(label, start, end, peak):
            arrs = [np.zeros(n, np.int8)] + [np.full(n, -1, np.int32) for _ in range(3)]
            for a, v in zip(arrs, (label, start, end, peak)):
                a[f] = v[idx]
            return FrameAudio(*arrs)

        none = np.full(graph.num_states, -1, np.int32)
        out[name] = (fa(graph.own_label, graph.own_start, graph.own_end, graph.own_peak),
                     fa(graph.partner_label, graph.partner_start, graph.partner_end, none))
    return out
