"""Audio constraints of a search window (paper Section 7.2), compiled into per-frame masks.

A path assigns one graph state to each output frame t = 0..T-1; its *associated audio* is the
sequence of the states' own (and partner) labels. An input segment [s, e) (frames, relative to the
window; segments crossing a window edge keep their true times) with tolerance tol becomes:

* type: the associated label must be the segment's kind on the core frames [s + tol, e - tol);
  the associated run therefore starts within tol of s and ends within tol of e, because
* idle: outside every own segment (and its tolerance margins) the own label must be IDLE;
* start/end margins [s - tol, s + tol) and [e - tol, e + tol) are free (the switch happens there);
* peak (PC only): some frame in [p - tol, p + tol] must be a state whose source frame is the F0
  peak of its own segment (checked when the peak window closes).

Listener responses (LR) constrain the own channel; partner hesitations (HP on the partner channel)
constrain the partner label the same way. Own hesitations are unconstrained. Switches:
``use_constraints=False`` (no audio constraint at all), ``use_lr``, ``use_hp``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..annotate.types import HP, IDLE, LR, PC
from .params import SearchParams

FREE = -1


@dataclass
class Constraints:
    """T frames. own_req/partner_req: (T,) required label code or FREE; peak_reset/peak_check: (T,) bool
    (the peak window of a PC opens / closes); peak_window: (T,) bool; segments: the list of constraints
    (kind, channel, start, peak, end in frames) for reporting."""

    num_frames: int
    fps: float
    tol: int
    own_req: np.ndarray
    partner_req: np.ndarray
    peak_window: np.ndarray
    peak_reset: np.ndarray
    peak_check: np.ndarray
    segments: list = field(default_factory=list)
    own_not: np.ndarray | None = None      # (T,) label forbidden on the own channel (FREE: none)
    partner_not: np.ndarray | None = None  # (T,) label forbidden on the partner channel

    @property
    def total(self) -> int:
        return len(self.segments)


def build_constraints(own_segments: pd.DataFrame, partner_segments: pd.DataFrame, num_frames: int, fps: float,
                      params: SearchParams) -> Constraints:
    T = int(num_frames)
    tol = int(round(float(params.tolerance) * fps))
    use_c, use_lr, use_hp = bool(params.use_constraints), bool(params.use_lr), bool(params.use_hp)
    own = np.full(T, IDLE if use_c else FREE, np.int32)
    par = np.full(T, FREE, np.int32)
    pw = np.zeros(T, bool)
    reset = np.zeros(T, bool)
    check = np.zeros(T, bool)
    own_not = np.full(T, FREE, np.int32)
    par_not = np.full(T, FREE, np.int32)
    segs = []
    if not use_c:
        return Constraints(T, fps, tol, own, par, pw, reset, check, segs, own_not, par_not)

    def forbid_outside(arr, code, s, e):
        """The run of ``code`` must start and end inside the margins: forbid it just outside them."""
        for t in (s - tol - 1, e + tol):
            if 0 <= t < T:
                arr[t] = code

    def frames(r):
        return int(round(r.start * fps)), int(round(r.end * fps)), int(round(getattr(r, "peak", np.nan) * fps)) \
            if np.isfinite(getattr(r, "peak", np.nan)) else None

    own_segments = own_segments if own_segments is not None else pd.DataFrame(columns=["kind", "start", "end"])
    for r in own_segments.itertuples(index=False):
        s, e, p = frames(r)
        lo, hi = max(0, s - tol), min(T, e + tol)
        if hi <= 0 or lo >= T:
            continue
        own[lo:hi] = FREE  # margins and unconstrained kinds
        code = {"PC": PC, "LR": LR}.get(r.kind)
        if code is None or (code == LR and not use_lr):
            continue
        a, b = max(0, s + tol), min(T, e - tol)
        if b <= a:  # its core lies outside the window: nothing to constrain here
            continue
        own[a:b] = code
        segs.append({"kind": r.kind, "channel": "own", "start": s, "end": e, "peak": p})
        forbid_outside(own_not, code, s, e)
        if code == PC and p is not None and 0 <= p - tol and p + tol < T:
            pw[p - tol:p + tol + 1] = True
            reset[p - tol] = True
            check[p + tol] = True
    if use_hp and partner_segments is not None:
        for r in partner_segments.itertuples(index=False):
            if r.kind != "HP":
                continue
            s, e, _ = frames(r)
            a, b = max(0, s + tol), min(T, e - tol)
            if b <= a:
                continue
            par[a:b] = HP
            segs.append({"kind": "PH", "channel": "partner", "start": s, "end": e, "peak": None})
            forbid_outside(par_not, HP, s, e)
    own_not[own != FREE] = FREE  # a hard requirement on a frame wins over a forbidden label
    par_not[par != FREE] = FREE
    idle_runs = _runs(own == IDLE)
    segs += [{"kind": "idle", "channel": "own", "start": a, "end": b, "peak": None} for a, b in idle_runs]
    return Constraints(T, fps, tol, own, par, pw, reset, check, segs, own_not, par_not)


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def label_ok(own_label, par_label, req):
    """Label requirements of one frame, for states of any shape (NumPy or JAX arrays; broadcasts):
    req = (own, partner, own_not, partner_not) codes, FREE (-1) for none."""
    own_r, par_r, own_n, par_n = req
    ok = (own_r < 0) | (own_label == own_r)
    ok &= (par_r < 0) | (par_label == par_r)
    ok &= ~((own_n >= 0) & (own_label == own_n))
    ok &= ~((par_n >= 0) & (par_label == par_n))
    return ok


def requirement_arrays(c: Constraints) -> tuple[np.ndarray, ...]:
    """(own, partner, own_not, partner_not), each (T,) int32, FREE where unconstrained."""
    free = np.full(c.num_frames, FREE, np.int32)
    return tuple(np.asarray(x if x is not None else free, np.int32)
                 for x in (c.own_req, c.partner_req, c.own_not, c.partner_not))


def state_ok_matrix(graph, c: Constraints) -> np.ndarray:
    """(T, S) bool: state s may be used at output frame t (label requirements only)."""
    return label_ok(graph.own_label.astype(np.int32)[None, :], graph.partner_label.astype(np.int32)[None, :],
                    tuple(r[:, None] for r in requirement_arrays(c)))


def median_synthetic_cost(graph) -> float:
    """The unit of the searches' sampling temperature (1.0 for a graph without synthetic edges)."""
    syn = graph.cost[graph.synthetic]
    return float(np.median(syn)) if syn.size else 1.0


def is_peak_state(graph) -> np.ndarray:
    """(S,) bool: the state's source frame is the F0 peak of its own PC segment."""
    return (graph.own_label == PC) & (graph.own_peak == graph.frame)
