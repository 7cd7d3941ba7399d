"""Retiming (``search.retime_factor``, ours; the paper's future work): where the matched source
segments of a path lie, and the warp that moves them onto the input's times.

With retiming a source clause (or listener response) may match an input segment whose end and F0
peak lie further off than the tolerance (``constraints``: the end within tol + floor(r (e - s)),
the peak within tol + floor(r (p - s)), the start within tol, or more with ``search.start_slack_factor``). :func:`retime_knots` finds, for each
own-channel constraint of the window of a retimable kind (the registry's,
:mod:`convsynth_jax.annotate.kinds`: PC and LR), the whole source instance the path placed for it (its start
st, peak pk and end en on the path's timeline) and returns a piecewise-linear warp with the knots
(s <- st, p <- pk, e <- en) plus the window's first and last frames: output frame t shows the
path at time ``np.interp(t, out_knots, path_knots)`` (``synth/retime.warp_motion``). Every matched
segment is moved exactly onto the input's times; in the idle runs either side the warp returns to
the identity (a knot a <- a about twice the shift away from the segment, inside the run), so only
idle frames next to a retimed segment stretch or shrink and the rest of the window keeps its
time. Knots outside the window's inner frames or out of order are dropped.
"""
from __future__ import annotations

import numpy as np

from ..annotate.kinds import IDLE, segment_kinds
from .constraints import Constraints, segment_info, slack_shift


def path_instances(graph, path) -> list[tuple]:
    """(label, start, peak or None, end) on the path's timeline of each own source segment the path
    plays (a run of consecutive frames of one source segment; its start may be < 0, its end > T)."""
    info = segment_info(graph)
    out = []
    prev = None
    for t, y in enumerate(np.asarray(path, np.int64)):
        o, L, q = (int(v) for v in info[y, :3])
        if o < 0:
            prev = None
            continue
        cont = (prev is not None and graph.clip[prev] == graph.clip[y] and graph.frame[y] == graph.frame[prev] + 1
                and o > 0)
        if not cont:
            st = t - o
            out.append((int(graph.own_label[y]), st, st + q if q >= 0 else None, st + L))
        prev = y
    return out


def _idle_runs(mask) -> list[tuple[int, int]]:
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist()))


def retime_knots(graph, c: Constraints, path, retime_factor: float):
    """(out_knots, path_knots) float64 arrays (increasing, from 0 to T - 1) of the warp onto the input's
    times, or None when nothing moves (module docstring)."""
    T = len(path)
    tol = c.tol
    inst = path_instances(graph, path)
    used: set = set()
    pairs, ident = [], []
    idle = _idle_runs(np.asarray(c.own_req) == IDLE)
    retimed = {k.name: k for k in segment_kinds("own") if k.retimable}
    for seg in sorted(c.segments, key=lambda x: x["start"]):
        kind = retimed.get(seg["kind"])
        if kind is None or seg["channel"] != "own":
            continue
        code = kind.code
        s, e, p = int(seg["start"]), int(seg["end"]), seg["peak"]
        p = None if p is None or not kind.has_peak else int(p)
        # the tolerances the constraints gave the segment (end and peak slack; the start slack of
        # ``search.start_slack_factor``), else those of the retiming factor
        etol = seg.get("end_tol", tol + int(np.floor(retime_factor * (e - s))))
        ptol = seg.get("peak_tol", tol + (int(np.floor(retime_factor * (p - s))) if p is not None else 0))
        stol = seg.get("start_tol", tol)
        best = None
        for i, (lab, st, pk, en) in enumerate(inst):
            d = slack_shift(st - s, tol)     # the start slack moves the whole instance
            if i in used or lab != code or abs(st - s) > stol or abs(en - d - e) > etol:
                continue
            if p is not None and (pk is None or abs(pk - d - p) > ptol):
                continue
            if best is None or abs(st - s) < abs(inst[best][1] - s):
                best = i
        if best is None:
            continue
        used.add(best)
        _, st, pk, en = inst[best]
        pairs += [(s, st), (e, en)] + ([(p, pk)] if p is not None and pk is not None else [])
        # back to the identity inside the idle runs either side (over twice the shift), so that what the
        # path plays between two input segments (e.g. an entry where the input has an own hesitation)
        # keeps its time
        lo, hi = min(s, st), max(e, en)
        before = [r for r in idle if r[1] <= lo]
        if before and s != st and before[-1][1] - 1 > before[-1][0]:
            ident.append(max(lo - 2 * abs(s - st) - 1, before[-1][0] + 1))
        after = [r for r in idle if r[0] >= hi - tol]
        if after and after[0][1] - 1 > hi and e != en:
            ident.append(min(hi + 2 * abs(e - en) + 1, after[0][1] - 1))
    pairs = sorted((o, q) for o, q in pairs if 0 < o < T - 1 and 0 < q < T - 1)
    knots = [(0, 0)]
    for o, q in pairs:
        if q <= knots[-1][1]:
            continue
        if o <= knots[-1][0]:
            # two knots on one output frame (a clause ends where the next begins, the path has frames
            # between them): the later one moves one frame on, within the tolerance
            o = knots[-1][0] + 1
        if o < T - 1:
            knots.append((o, q))
    if T - 1 > knots[-1][0] and T - 1 > knots[-1][1]:
        knots.append((T - 1, T - 1))
    for a in sorted(x for x in set(ident) if 0 < x < T - 1):   # only where they fit between the segments' knots
        i = next(k for k, (o, _) in enumerate(knots) if o >= a)
        if knots[i - 1][0] < a < knots[i][0] and knots[i - 1][1] < a < knots[i][1]:
            knots.insert(i, (a, a))
    k = np.asarray(knots, np.float64)
    if np.array_equal(k[:, 0], k[:, 1]):
        return None
    return k[:, 0], k[:, 1]
