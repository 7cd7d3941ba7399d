"""Gesture phases (paper Sec. 4): preparation, stroke (with one or more peaks), hold, retraction,
and handedness, detected from root-relative wrist motion or read from a CSV.

Automatic detection (ours; the paper annotated by hand): the rest pose is the mean of the first
``rest_frames`` frames; a hand's *excursion* is its root-relative wrist distance from rest. The
gesturing hands are those whose excursion exceeds ``hand_min_cm`` and ``hand_rel_frac`` of the
other's. On the largest excursion e(t): the gesture is active where e > active_frac * max(e)
(t_Pb .. t_Re), stroke-and-hold where e > stroke_frac * max(e) (t_Sb .. t_Se), so preparation is
t_Pb .. t_Sb - 1 and retraction t_Se + 1 .. t_Re. Stroke peaks are minima of root-relative wrist
speed inside the stroke (the hand arriving / reversing) with prominence >= peak_prominence_frac
times the peak speed of the gesture: a raise-hand gesture has one, a wave several.

CSV override columns: gesture (file stem), t_pb, t_pe, t_sb, t_se, t_rb, t_re (seconds), peaks
(seconds, ';'-separated), handedness (l | r | both), type (beat, deictic, iconic, metaphoric, ...);
a missing column keeps the detected value.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.signal import find_peaks

from ..errors import MissingFileError, WalkTalkError
from ..kinematics import forward_kinematics_np
from ..skeleton import Motion
from .body import Body, find_body
from .params import GaitParams, PhaseParams


@dataclass(frozen=True)
class Phases:
    """Frame indices t_Pb <= t_Pe < t_Sb <= peaks <= t_Se < t_Rb <= t_Re (paper Sec. 4)."""

    pb: int
    pe: int
    sb: int
    se: int
    rb: int
    re: int
    peaks: tuple[int, ...]

    def shifted(self, d: int) -> Phases:
        return Phases(self.pb + d, self.pe + d, self.sb + d, self.se + d, self.rb + d, self.re + d,
                      tuple(p + d for p in self.peaks))


@dataclass(frozen=True)
class Gesture:
    motion: Motion
    phases: Phases
    handedness: str        # "l", "r" or "both"
    kind: str = "beat"     # McNeill type; "deictic" gestures are not stylized
    name: str = ""

    @property
    def sides(self) -> tuple[str, ...]:
        return ("l", "r") if self.handedness == "both" else (self.handedness,)

    @property
    def single_peak(self) -> bool:
        return len(self.phases.peaks) == 1


def validate_phases(ph: Phases, num_frames: int, path: str) -> None:
    """Raise a :class:`WalkTalkError` naming the frames when phases are out of order or outside the clip."""
    seq = [("t_Pb", ph.pb), ("t_Pe", ph.pe), ("t_Sb", ph.sb), ("t_Se", ph.se), ("t_Rb", ph.rb), ("t_Re", ph.re)]
    if ph.pb < 0 or ph.re >= num_frames:
        raise WalkTalkError(f"phases outside the clip of {num_frames} frames: {dict(seq)}", path, f"frame {ph.pb if ph.pb < 0 else ph.re}")
    strict = {("t_Pe", "t_Sb"), ("t_Se", "t_Rb")}
    for (na, a), (nb, b) in itertools.pairwise(seq):
        if b < a or ((na, nb) in strict and b <= a):
            raise WalkTalkError(f"gesture phases out of order: {na}={a} then {nb}={b} (expected "
                                "t_Pb <= t_Pe < t_Sb <= t_Se < t_Rb <= t_Re)", path, f"frame {b}")
    for p in ph.peaks:
        if not ph.sb <= p <= ph.se:
            raise WalkTalkError(f"stroke peak at frame {p} outside the stroke t_Sb={ph.sb}..t_Se={ph.se}", path, f"frame {p}")
    if not ph.peaks:
        raise WalkTalkError("gesture has no stroke peak", path, f"frames {ph.sb}-{ph.se}")


def check_standing(motion: Motion, p: GaitParams, body: Body | None = None, positions=None) -> None:
    """A gesture clip must be recorded standing: its root may not travel more than max_root_travel_cm."""
    body = body or find_body(motion.skeleton, motion.name)
    pos = forward_kinematics_np(motion) if positions is None else positions
    root = pos[:, body.joints["hips"]][:, [0, 2]]
    d = np.linalg.norm(root - root[0], axis=1)
    if d.max() > p.max_root_travel_cm:
        f = int(np.argmax(d > p.max_root_travel_cm))
        raise WalkTalkError(f"gesture clip is not standing: the root travels {d.max():.1f} cm "
                            f"(> {p.max_root_travel_cm} cm), first beyond at frame {f}", motion.name, f"frame {f}")


def wrist_tracks(motion: Motion, body: Body, positions=None) -> dict:
    """Root-relative wrist positions (F, 3) per side."""
    pos = forward_kinematics_np(motion) if positions is None else positions
    root = pos[:, body.joints["hips"]]
    return {s: pos[:, body.joints[f"hand_{s}"]] - root for s in ("l", "r")}


def detect_phases(motion: Motion, p: PhaseParams, body: Body | None = None, positions=None) -> tuple[Phases, str]:
    """Automatic phases and handedness of a standing gesture clip (see module docstring)."""
    body = body or find_body(motion.skeleton, motion.name)
    w = wrist_tracks(motion, body, positions)
    n = motion.num_frames
    rest_n = max(1, min(p.rest_frames, n))
    exc = {s: np.linalg.norm(w[s] - w[s][:rest_n].mean(0), axis=1) for s in w}
    mx = {s: float(exc[s].max()) for s in exc}
    big = max(mx.values())
    sides = [s for s in ("l", "r") if mx[s] >= p.hand_min_cm and mx[s] >= p.hand_rel_frac * big]
    if not sides:
        raise WalkTalkError(f"no gesture found: wrist excursions {mx['l']:.1f} (left), {mx['r']:.1f} (right) cm "
                            f"below {p.hand_min_cm} cm", motion.name, f"frames 0-{n - 1}")
    hand = "both" if len(sides) == 2 else sides[0]
    main = max(sides, key=lambda s: mx[s])
    e = exc[main]
    active = np.flatnonzero(e > p.active_frac * mx[main])
    stroke = np.flatnonzero(e > p.stroke_frac * mx[main])
    pb, re_ = int(active[0]), int(active[-1])
    sb, se = int(stroke[0]), int(stroke[-1])
    pb = min(pb, sb - 1)
    re_ = max(re_, se + 1)
    if pb < 0 or re_ >= n:
        raise WalkTalkError(f"gesture not bounded by rest: active frames {pb}..{re_} of {n}", motion.name,
                            f"frame {max(0, min(pb, n - 1))}")
    speed = np.zeros(n)
    speed[1:] = np.linalg.norm(np.diff(w[main], axis=0), axis=1) * motion.fps
    speed[0] = speed[1] if n > 1 else 0.0
    seg = speed[pb:re_ + 1]
    idx, _ = find_peaks(-seg, prominence=p.peak_prominence_frac * float(seg.max()))
    peaks = tuple(int(pb + i) for i in idx if sb <= pb + i <= se)
    if not peaks:
        peaks = (int(sb + np.argmin(speed[sb:se + 1])),)
    ph = Phases(pb, sb - 1, sb, se, se + 1, re_, peaks)
    validate_phases(ph, n, motion.name)
    return ph, hand


def load_phase_table(path: str | Path) -> pd.DataFrame:
    path = Path(path)
    if not path.is_file():
        raise MissingFileError("gesture phase CSV not found", path)
    df = pd.read_csv(path)
    if "gesture" not in df.columns:
        raise WalkTalkError("phase CSV needs a 'gesture' column (file stem)", path, "line 1")
    return df


def apply_phase_override(g: Gesture, table: pd.DataFrame, table_path: str) -> Gesture:
    """Replace detected phases / handedness / type by a CSV row for this gesture (if any)."""
    stem = Path(g.name).stem
    rows = table.index[table["gesture"].astype(str) == stem]
    if len(rows) == 0:
        return g
    i = int(rows[0])
    row = table.loc[i]
    fps = g.motion.fps
    ph = g.phases
    vals = {}
    for key in ("pb", "pe", "sb", "se", "rb", "re"):
        col = f"t_{key}"
        if col in row and pd.notna(row[col]):
            vals[key] = round(float(row[col]) * fps)
    peaks = ph.peaks
    if "peaks" in row and pd.notna(row["peaks"]):
        peaks = tuple(round(float(x) * fps) for x in str(row["peaks"]).split(";") if x.strip())
    ph = replace(ph, **vals, peaks=peaks)
    try:
        validate_phases(ph, g.motion.num_frames, g.name)
    except WalkTalkError as e:
        raise WalkTalkError(f"{e.reason} (from {table_path} line {i + 2})", g.name, e.where) from None
    hand = str(row["handedness"]) if "handedness" in row and pd.notna(row["handedness"]) else g.handedness
    if hand not in ("l", "r", "both"):
        raise WalkTalkError(f"handedness must be l, r or both, got {hand!r}", table_path, f"line {i + 2}")
    kind = str(row["type"]) if "type" in row and pd.notna(row["type"]) else g.kind
    return replace(g, phases=ph, handedness=hand, kind=kind)


def make_gesture(motion: Motion, gait: GaitParams, phases: PhaseParams, body: Body | None = None,
                 kind: str = "beat") -> Gesture:
    """Check a standing gesture clip and detect its phases."""
    body = body or find_body(motion.skeleton, motion.name)
    pos = forward_kinematics_np(motion)
    check_standing(motion, gait, body, pos)
    ph, hand = detect_phases(motion, phases, body, pos)
    return Gesture(motion, ph, hand, kind, motion.name)
