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
constrain the partner label the same way. Own hesitations are unconstrained. The kinds, their
channels, peaks, retiming and switches are the registry's (:mod:`convsynth_jax.annotate.kinds`);
switches: ``use_constraints=False`` (no audio constraint at all), ``use_lr``, ``use_hp``.

Two matching modes (``search.matching``):

* ``labels`` (ours, relaxed; the rules above): one input clause may be stitched from several
  source clauses, the peak rule only asks for some source peak frame within tol, and segments of
  2 tol or less (no core frames) are unconstrained. Two segments of one kind that touch (a clause
  split at a word boundary) get a frame between them where the label is forbidden
  (:func:`_split_touching`), so one run cannot cover both.
* ``paper`` (default; Section 7.2 as the paper states it): each input segment (own PC, own LR,
  partner HP) is matched by ONE source segment of the same kind, played whole, whose start, F0
  peak (PC) and end, placed on the output timeline, lie within tol of the input's. Short segments
  are constrained like all others; idle stays idle.

Encoding of ``paper`` (:class:`PaperArrays`; all per-frame arrays have fixed size T, so the beam
kernel needs no variable-size bookkeeping). Every graph state carries its offset o in its own
source segment, the segment's length L and its peak offset q (and the partner segment's offset
and length), from the database annotation. A path is *in* a source segment instance of a
constrained kind (own PC, own LR when use_lr, partner HP when use_hp):

* contiguity: a synthetic transition may neither leave a source segment of a constrained kind
  before its last frame (o < L - 1) nor enter one after its first frame (o > 0), so every
  instance is played whole, and its placement on the output timeline is fixed when it is entered:
  start t - o, end t - o + L, peak t - o + q (t: the output frame; o = 0 except at frame 0);
* entry windows: an input segment [s, e) opens an entry window [s - tol, s + tol] (windows of
  consecutive segments of one channel that would overlap are split at the midpoint of their
  starts: a restriction of ours, sound but not complete). Entering an instance of kind K is
  allowed only in a window of kind K whose segment it matches (start, end and peak within tol),
  at most once per window (a per-path flag, reset when the window opens), or in a *free* frame
  (inside the range of an input segment that is not a constraint, e.g. LR when use_lr is off);
  the flag must be set when the window closes;
* the label masks of ``labels`` stay (core frames need the kind, idle frames need idle), the
  "forbidden just outside" labels do not (the placement check replaces them).

Best effort (``search.on_failure=best_effort``, ours): ``relaxed`` names constraints by their
:func:`constraint_key` (kind, start frame, end frame); a relaxed segment is built like a segment of
an unconstrained kind (its range is free), a relaxed idle run frees its frames
(:mod:`convsynth_jax.search.relax` picks them).

Retiming (``search.retime_factor`` r > 0, ours, ``paper`` only): the end of an own clause or response
[s, e) may lie within tol + floor(r (e - s)) frames of the input's and its F0 peak within
tol + floor(r (p - s)) (the start keeps tol); the label core and the idle rule shrink by the same end
slack. Realization then warps the matched segment onto the input's times (:func:`retime_knots`,
``synth/retime.py``).

Segments crossing the window start are matched by the frame-0 state's placement (its offset may be
> 0); a segment counts as a constraint when its entry window closes inside the window, or it began
before the window and its core reaches into it. :mod:`convsynth_jax.search.check` re-verifies the
rule from the path's source frames and the database segments, without this encoding.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import pandas as pd

from ..annotate.kinds import HP, IDLE, kind_of_segment, segment_kinds
from ..errors import ConfigError
from .params import SearchParams

FREE = -1
NO_PEAK = -(1 << 20)   # PaperArrays.own_peak where the input segment has no F0 peak
MATCHING_MODES = ("paper", "labels")


class EntryWindows(NamedTuple):
    """One channel's entry windows of ``search.matching=paper`` at each frame (T,) (or one frame's
    values): :class:`PaperArrays` and the kernels' padded inputs."""
    kind: object        # label code of the window covering the frame, FREE for none
    start: object       # the window's input segment (frames on the output timeline)
    end: object
    peak: object        # NO_PEAK for none
    free: object        # bool: entries of any kind allowed
    reset: object       # bool: a window opens (its flag is cleared)
    check: object       # bool: a window closes (its flag must be set)
    end_tol: object     # int32: the end tolerance (tol, + the retiming slack)
    peak_tol: object    # int32: the peak tolerance
    start_tol: object   # int32: the start tolerance (tol, + the start slack of ``search.start_slack_factor``)


@dataclass
class PaperArrays:
    """Per-frame arrays of ``search.matching=paper`` (T frames; see the module docstring).

    own_kind/par_kind: (T,) label code of the entry window covering the frame, FREE for none;
    own_start/own_end/own_peak, par_start/par_end: (T,) that window's input segment (frames on the
    output timeline, NO_PEAK for no peak); own_free/par_free: (T,) bool, entries of any kind allowed;
    own_reset/own_check, par_reset/par_check: (T,) bool, an entry window opens / closes (the flag must
    be set); own_codes/par_codes: bit masks of the constrained label codes (bit k: code k)."""

    own_kind: np.ndarray
    own_start: np.ndarray
    own_end: np.ndarray
    own_peak: np.ndarray
    own_free: np.ndarray
    own_reset: np.ndarray
    own_check: np.ndarray
    own_end_tol: np.ndarray     # (T,) int32: the window's end tolerance (tol, + the retiming slack)
    own_peak_tol: np.ndarray    # (T,) int32: the window's peak tolerance
    own_start_tol: np.ndarray   # (T,) int32: the window's start tolerance
    par_kind: np.ndarray
    par_start: np.ndarray
    par_end: np.ndarray
    par_free: np.ndarray
    par_reset: np.ndarray
    par_check: np.ndarray
    own_codes: int
    par_codes: int

    par_tol: int = 0           # the partner windows' end tolerance (tol)

    def own(self) -> EntryWindows:
        """The own channel's windows, each (T,)."""
        return EntryWindows(self.own_kind, self.own_start, self.own_end, self.own_peak, self.own_free,
                            self.own_reset, self.own_check, self.own_end_tol, self.own_peak_tol, self.own_start_tol)

    def partner(self) -> EntryWindows:
        """The partner channel's windows, each (T,) (no peak; both tolerances tol)."""
        nopk = np.full_like(self.par_start, NO_PEAK)
        tol = np.full_like(self.par_start, self.par_tol)
        return EntryWindows(self.par_kind, self.par_start, self.par_end, nopk, self.par_free, self.par_reset,
                            self.par_check, tol, tol, tol)


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
    paper: PaperArrays | None = None       # search.matching=paper: the entry windows (else None)

    @property
    def total(self) -> int:
        return len(self.segments)


def constraint_key(seg: dict) -> tuple:
    """(kind, start frame, end frame): names one constraint of a window (``Constraints.segments`` and
    the checker's details alike); kinds PC, LR, PH (partner hesitation) and idle."""
    return (str(seg["kind"]), int(seg["start"]), int(seg["end"]))


def build_constraints(own_segments: pd.DataFrame, partner_segments: pd.DataFrame, num_frames: int, fps: float,
                      params: SearchParams, relaxed=frozenset()) -> Constraints:
    """The window's constraints; ``relaxed``: keys (:func:`constraint_key`) of constraints to leave out
    (best effort, ours)."""
    if params.matching not in MATCHING_MODES:
        raise ConfigError(f"search.matching must be one of {list(MATCHING_MODES)}, got {params.matching!r}")
    if not 0.0 <= float(params.retime_factor) < 1.0:
        raise ConfigError(f"search.retime_factor must lie in [0, 1), got {params.retime_factor}")
    if not 0.0 <= float(params.start_slack_factor) < 1.0:
        raise ConfigError(f"search.start_slack_factor must lie in [0, 1), got {params.start_slack_factor}")
    if float(params.start_slack_factor) > 0 and float(params.retime_factor) <= 0:
        raise ConfigError("search.start_slack_factor > 0 needs search.retime_factor > 0: the warp that retiming "
                          "builds is what moves a slack start onto the input's")
    relaxed = frozenset(relaxed)
    if params.matching == "paper":
        return _build_paper(own_segments, partner_segments, num_frames, fps, params, relaxed)
    if float(params.retime_factor) > 0:
        raise ConfigError("search.retime_factor > 0 needs search.matching=paper: labels matching may stitch an "
                          "input clause from several source clauses, so there is no one source clause to warp")
    T = int(num_frames)
    tol = int(round(float(params.tolerance) * fps))
    use_c = bool(params.use_constraints)
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

    own_segments = own_segments if own_segments is not None else pd.DataFrame(columns=["kind", "start", "end"])
    for r in own_segments.itertuples(index=False):
        s, e, p = _seg_frames(r, fps)
        lo, hi = max(0, s - tol), min(T, e + tol)
        if hi <= 0 or lo >= T:
            continue
        own[lo:hi] = FREE  # margins and unconstrained kinds
        kind = kind_of_segment("own", r.kind)
        if kind is None or not kind.enabled(params) or (kind.name, s, e) in relaxed:
            continue
        code = kind.code
        a, b = max(0, s + tol), min(T, e - tol)
        if b <= a:  # its core lies outside the window: nothing to constrain here
            continue
        own[a:b] = code
        segs.append({"kind": kind.name, "channel": "own", "start": s, "end": e, "peak": p})
        forbid_outside(own_not, code, s, e)
        if kind.has_peak and p is not None and 0 <= p - tol and p + tol < T:
            pw[p - tol:p + tol + 1] = True
            reset[p - tol] = True
            check[p + tol] = True
    if partner_segments is not None and any(k.enabled(params) for k in segment_kinds("partner")):
        for r in partner_segments.itertuples(index=False):
            kind = kind_of_segment("partner", r.kind)
            if kind is None or not kind.enabled(params):
                continue
            s, e, _ = _seg_frames(r, fps)
            a, b = max(0, s + tol), min(T, e - tol)
            if b <= a or (kind.name, s, e) in relaxed:
                continue
            par[a:b] = kind.code
            segs.append({"kind": kind.name, "channel": "partner", "start": s, "end": e, "peak": None})
            forbid_outside(par_not, kind.code, s, e)
    _split_touching(own_not, own, [x for x in segs if x["channel"] == "own"], tol)
    _split_touching(par_not, par, [x for x in segs if x["channel"] == "partner"], tol)
    idle_runs = _runs(own == IDLE)
    for a, b in idle_runs:
        if ("idle", a, b) in relaxed:
            own[a:b] = FREE
        else:
            segs.append({"kind": "idle", "channel": "own", "start": int(a), "end": int(b), "peak": None})
    own_not[own != FREE] = FREE  # a hard requirement on a frame wins over a forbidden label
    par_not[par != FREE] = FREE
    return Constraints(T, fps, tol, own, par, pw, reset, check, segs, own_not, par_not)


def _split_touching(forbid: np.ndarray, req: np.ndarray, segs: list, tol: int) -> None:
    """``labels``: two constrained segments of one kind and channel that touch or overlap ([s1, e1),
    [s2, e2) with s2 <= e1: clauses split at a word boundary) share their margins, so one run of the
    label could cover both, and neither run would start and end near its segment (the
    search claimed such windows, the checker rejected them). The label is forbidden at one frame
    m = (e1 + s2) // 2 between them, so the first run ends within tol of e1 and the second starts
    within tol of s2 (ours: sound, not complete; a break elsewhere in the margins would do too).
    Segments whose cores overlap (m outside [e1 - tol, s2 + tol - 1]) cannot both be met by label
    runs; they are left as they are."""
    code = {k.name: k.code for k in segment_kinds()}
    items = sorted(segs, key=lambda x: (x["start"], x["end"]))
    T = forbid.shape[0]
    for x, y in zip(items[:-1], items[1:]):
        if x["kind"] != y["kind"] or y["start"] > x["end"]:
            continue
        m = (x["end"] + y["start"]) // 2
        if x["end"] - tol <= m <= y["start"] + tol - 1 and 0 <= m < T and req[m] == FREE:
            forbid[m] = code[x["kind"]]


def _slack(retime: float, s: int, x: int, tol: int, T: int) -> int:
    """Retiming slack (frames) of an end or peak x of a segment starting at s: floor(retime (x - s)),
    bounded so that every source placement it admits lies inside the window's inner frames 1..T - 2,
    where the warp can move it (0 without retiming)."""
    if retime <= 0:
        return 0
    return max(0, min(int(np.floor(retime * (x - s))), T - 2 - x - tol, x - tol - 1))


def _start_slacks(own_segments, fps, factor: float, tol: int, T: int) -> dict:
    """Start slack (frames) of each own input segment, keyed by its (start, end) frames:
    floor(factor * g), g the idle gap before it (frames since the end of the previous own segment of any
    kind; from the window's first frame for the first), bounded like :func:`_slack` so that every start
    it admits lies inside the window's inner frames. Empty without a factor."""
    if factor <= 0 or own_segments is None or not len(own_segments):
        return {}
    frames = sorted(_seg_frames(r, fps)[:2] for r in own_segments.itertuples(index=False))
    out, prev_end = {}, 0
    for s, e in frames:
        g = max(0, s - prev_end)
        out[(s, e)] = max(0, min(int(np.floor(factor * g)), T - 2 - s - tol, s - tol - 1))
        prev_end = max(prev_end, e)
    return out


def _seg_frames(r, fps):
    pk = getattr(r, "peak", np.nan)
    pk = int(round(pk * fps)) if pk is not None and np.isfinite(pk) else None
    return int(round(r.start * fps)), int(round(r.end * fps)), pk


def _build_paper(own_segments, partner_segments, num_frames, fps, params, relaxed=frozenset()) -> Constraints:
    """``search.matching=paper``: label masks plus entry windows (module docstring)."""
    T = int(num_frames)
    tol = int(round(float(params.tolerance) * fps))
    use_c = bool(params.use_constraints)
    retime = float(params.retime_factor)
    own = np.full(T, IDLE if use_c else FREE, np.int32)
    par = np.full(T, FREE, np.int32)
    zeros = np.zeros(T, bool)
    segs = []

    def channel():
        return dict(kind=np.full(T, FREE, np.int32), start=np.zeros(T, np.int32), end=np.zeros(T, np.int32),
                    peak=np.full(T, NO_PEAK, np.int32), free=np.zeros(T, bool), reset=np.zeros(T, bool),
                    check=np.zeros(T, bool), etol=np.full(T, tol, np.int32), ptol=np.full(T, tol, np.int32),
                    stol=np.full(T, tol, np.int32))

    ch = {"own": channel(), "partner": channel()}
    if not use_c:
        pa = PaperArrays(*(ch["own"][k] for k in ("kind", "start", "end", "peak")), np.ones(T, bool), zeros, zeros,
                         ch["own"]["etol"], ch["own"]["ptol"], ch["own"]["stol"],
                         *(ch["partner"][k] for k in ("kind", "start", "end")), np.ones(T, bool), zeros, zeros, 0, 0,
                         tol)
        return Constraints(T, fps, tol, own, par, zeros, zeros, zeros, segs, np.full(T, FREE, np.int32),
                           np.full(T, FREE, np.int32), pa)
    own_codes = sum(1 << k.code for k in segment_kinds("own") if k.enabled(params))
    par_codes = sum(1 << k.code for k in segment_kinds("partner") if k.enabled(params))
    own_plain = own.copy()    # the own requirement without the retiming slack (idle runs are named by it)
    end_zone = np.zeros(T, bool)       # retiming: frames around a constrained clause's end (+- tol + slack)
    unconstrained = np.zeros(T, bool)  # the ranges of input segments of unconstrained kinds (own HP, ...)
    counted = {"own": [], "partner": []}   # (code, s, e, peak, kind name) of the constraints
    free_ranges = {"own": [], "partner": []}
    own_segments = own_segments if own_segments is not None else pd.DataFrame(columns=["kind", "start", "end"])
    start_slacks = _start_slacks(own_segments, fps, float(params.start_slack_factor) if retime > 0 else 0.0, tol, T)
    start_zone = np.zeros(T, bool)     # start slack: frames before a constrained segment's start the warp moves
    for r in own_segments.itertuples(index=False):
        s, e, p = _seg_frames(r, fps)
        kind = kind_of_segment("own", r.kind)
        code = kind.code if kind is not None else None
        # retiming (ours): the end may lie up to ``slack`` frames further off, the core and idle rule shrink;
        # only as far as the warp can move it (inside the window); with the start slack the start too
        retimable = kind is not None and kind.retimable
        slack = _slack(retime, s, e, tol, T) if retimable else 0
        sslack = start_slacks.get((s, e), 0) if retimable and code is not None and (own_codes >> code) & 1 else 0
        lo, hi = max(0, s - tol - sslack), min(T, e + tol + slack)
        if hi <= 0 or lo >= T:
            continue
        own[lo:hi] = FREE
        own_plain[max(0, s - tol):min(T, e + tol)] = FREE
        if code is None or not (own_codes >> code) & 1 or (kind.name, s, e) in relaxed:
            free_ranges["own"].append((lo, hi))
            if code is None or not (own_codes >> code) & 1:
                unconstrained[lo:hi] = True
            continue
        if retime > 0:
            end_zone[max(0, e - tol - slack):hi] = True
            if sslack:   # the whole entry window: the warp moves what the path plays there by up to the slack
                start_zone[lo:max(lo, min(T, s + tol + sslack))] = True
        c = s + tol
        a, b = max(0, s + tol), min(T, e - tol - slack)
        if 0 <= c < T or (c < 0 and min(T, e - tol) > a):
            pk = p if kind.has_peak else None
            pslack = _slack(retime, s, p, tol, T) if pk is not None and kind.retimable else 0
            counted["own"].append((code, s, e, pk, kind.name, slack, pslack, sslack))
        else:
            free_ranges["own"].append((lo, hi))
        if b > a:
            own[a:b] = code
    if partner_segments is not None and par_codes:
        for r in partner_segments.itertuples(index=False):
            kind = kind_of_segment("partner", r.kind)
            if kind is None or not (par_codes >> kind.code) & 1:
                continue
            s, e, _ = _seg_frames(r, fps)
            c = s + tol
            a, b = max(0, s + tol), min(T, e - tol)
            if (kind.name, s, e) in relaxed:
                pass    # no label core; the range stays free (below)
            elif 0 <= c < T or (c < 0 and b > a):
                counted["partner"].append((kind.code, s, e, None, kind.name, 0, 0, 0))
                if b > a:
                    par[a:b] = kind.code
                continue
            if max(0, s - tol) < min(T, e + tol):
                free_ranges["partner"].append((max(0, s - tol), min(T, e + tol)))
    # the partner channel has no idle rule: a partner HP may be entered anywhere outside the range
    # [s - tol, e + tol) of an input HP; the own channel's free frames are those of input segments
    # that are no constraint (outside them own_req already asks for idle or the core's kind)
    ch["partner"]["free"][:] = True
    for name in ("own", "partner"):
        arr = ch[name]
        for lo, hi in free_ranges[name]:
            arr["free"][lo:hi] = True
        items = sorted(counted[name], key=lambda x: x[1])
        for i, (code, s, e, p, kind, slack, pslack, sslack) in enumerate(items):
            lo, hi = s - tol - sslack, s + tol + sslack    # entry window [lo, hi]
            if i > 0 and items[i - 1][1] + tol + items[i - 1][7] >= lo:   # overlaps the previous window: split (ours)
                lo = (items[i - 1][1] + s) // 2 + 1
            if i + 1 < len(items) and items[i + 1][1] - tol - items[i + 1][7] <= hi:
                hi = (s + items[i + 1][1]) // 2
            if hi < 0:                                     # began before the window: frame 0 carries it
                lo = hi = 0
            lo, hi_c = max(0, lo), min(T - 1, hi)
            if hi_c >= lo:
                arr["kind"][lo:hi_c + 1] = code
                arr["start"][lo:hi_c + 1], arr["end"][lo:hi_c + 1] = s, e
                arr["peak"][lo:hi_c + 1] = NO_PEAK if p is None else p
                arr["etol"][lo:hi_c + 1], arr["ptol"][lo:hi_c + 1] = tol + slack, tol + pslack
                arr["stol"][lo:hi_c + 1] = tol + sslack
                arr["reset"][lo] = True
                if s + tol >= 0 and hi_c == hi:
                    arr["check"][hi] = True
            arr["free"][max(0, s - tol - sslack):max(0, min(T, e + tol + slack))] = False
            segs.append({"kind": kind, "channel": name, "start": s, "end": e, "peak": p, "start_tol": tol + sslack,
                         "end_tol": tol + slack, "peak_tol": tol + pslack})
        arr["free"] &= arr["kind"] < 0
    own_not = np.full(T, FREE, np.int32)
    # retiming: the frames around a clause's end may hold the clause's own end, but no own hesitation
    # (the warp moves the path's frames after a source clause's end to the input's end, so one entered
    # there would land in the input's idle run), unless the input has an own segment of its own there
    # the start slack's frames before a clause's start likewise (the warp moves them into the clause's start)
    own_not[(end_zone | start_zone) & ~unconstrained & (own == FREE)] = HP
    for a, b in _runs(own_plain == IDLE):
        if ("idle", a, b) in relaxed:   # best effort: the run is free, entries of any kind allowed
            own[a:b] = np.where(own[a:b] == IDLE, FREE, own[a:b])
            own_not[a:b] = FREE
            ch["own"]["free"][a:b] = ch["own"]["kind"][a:b] < 0
        else:
            segs.append({"kind": "idle", "channel": "own", "start": int(a), "end": int(b), "peak": None})
    pa = PaperArrays(*(ch["own"][k] for k in ("kind", "start", "end", "peak", "free", "reset", "check", "etol", "ptol",
                                               "stol")),
                     *(ch["partner"][k] for k in ("kind", "start", "end", "free", "reset", "check")),
                     own_codes, par_codes, tol)
    return Constraints(T, fps, tol, own, par, zeros.copy(), zeros.copy(), zeros.copy(), segs, own_not,
                       np.full(T, FREE, np.int32), pa)


def segment_info(graph) -> np.ndarray:
    """(S, 5) int32 per state: own offset in its source segment, own segment length, own peak offset
    (-1: none), partner offset, partner segment length (offsets -1 and lengths 0 where idle)."""
    own_on = (graph.own_label != IDLE) & (graph.own_start >= 0)
    par_on = (graph.partner_label != IDLE) & (graph.partner_start >= 0)
    f = graph.frame.astype(np.int64)
    out = np.stack([np.where(own_on, f - graph.own_start, -1), np.where(own_on, graph.own_end - graph.own_start, 0),
                    np.where(own_on & (graph.own_peak >= 0), graph.own_peak - graph.own_start, -1),
                    np.where(par_on, f - graph.partner_start, -1),
                    np.where(par_on, graph.partner_end - graph.partner_start, 0)], axis=1)
    return out.astype(np.int32)


def placement_ok(label, offset, length, peak_off, t, win, tol):
    """Does a source segment instance (label, offset of the state, length, peak offset) at output frame
    t match the entry window ``win`` = (kind, start, end, peak[, end tolerance, peak tolerance[, start
    tolerance]]) of that frame? The start within its tolerance, the end and peak within theirs (default
    ``tol``; larger with retiming) once the instance is moved back by its start's shift beyond ``tol``
    (:func:`slack_shift`: the start slack moves the whole instance). Operators only, so it works on
    NumPy and JAX arrays alike."""
    kind, s, e, p = win[:4]
    etol, ptol = (win[4], win[5]) if len(win) > 4 else (tol, tol)
    stol = win[6] if len(win) > 6 else tol
    st = t - offset
    d = slack_shift(st - s, tol)
    ok = (label == kind) & (st - s <= stol) & (s - st <= stol)
    ok = ok & (st - d + length - e <= etol) & (e - st + d - length <= etol)
    pk = st - d + peak_off - p
    return ok & ((p == NO_PEAK) | ((peak_off >= 0) & (pk <= ptol) & (-pk <= ptol)))


def slack_shift(x, tol):
    """The part of a start's offset x (placed minus input start, frames) beyond the tolerance ``tol``,
    which only the start slack admits: 0 for |x| <= tol, else x - tol or x + tol. The whole instance is
    read as moved back by it, so within ``tol`` the rule is the one without slack. Operators only
    (NumPy, JAX and Python ints)."""
    return (x - tol) * (x > tol) + (x + tol) * (x < -tol)


def paper_channel_step(label_x, off_x, len_x, label_y, off_y, len_y, peak_y, synthetic, first, t, flag, arrs,
                       codes, tol):
    """One channel's ``paper`` rule for a transition x -> y arriving at output frame t (``first``: t is
    frame 0 and y the start state; x and synthetic are then ignored). arrs: that frame's
    (kind, start, end, peak, free, reset, check, end tolerance, peak tolerance). Returns (ok, new flag).
    Operators only (NumPy/JAX)."""
    kind, s, e, p, free, reset, check, etol, ptol, stol = arrs
    cons_x = ((codes >> label_x) & 1) == 1
    cons_y = ((codes >> label_y) & 1) == 1
    mid_x = cons_x & (off_x < len_x - 1)
    mid_y = cons_y & (off_y > 0)
    contiguous = first | ~synthetic | ~(mid_x | mid_y)
    entry = cons_y & (first | (off_y == 0))
    f0 = flag & ~reset
    matched = entry & placement_ok(label_y, off_y, len_y, peak_y, t, (kind, s, e, p, etol, ptol, stol), tol) & ~f0
    ok = contiguous & (~entry | free | matched)
    f1 = f0 | matched
    return ok & (~check | f1), f1


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
    """(S,) bool: the state's source frame is the F0 peak of its own segment, of a kind with a peak (PC)."""
    peaked = [k.code for k in segment_kinds("own") if k.has_peak]
    return np.isin(graph.own_label, peaked) & (graph.own_peak == graph.frame)


def constrained(c: Constraints) -> bool:
    """Does the window constrain anything (else every path completes and the look-ahead is skipped)?"""
    free = all((np.asarray(r) < 0).all() for r in requirement_arrays(c))
    flags = c.peak_check.any() or (c.paper is not None and (c.paper.own_check.any() or c.paper.par_check.any()
                                                           or not c.paper.own_free.all() or not c.paper.par_free.all()))
    return not (free and not flags)
