"""Locomotion loops (paper Sec. 3.1 and 4): contacts, heel strikes, contact/flight phases, loops.

A foot is *down* when its ankle or toe is within ``height_tol_cm`` of that point's lowest height
in the clip and moves slower than ``speed_tol_cms`` horizontally; a heel strike is the first frame
of a down run.

Contact and flight phases follow the paper's definition (Sec. 3.1, Fig. 3), each in two readings
(:func:`contact_phases`), with every threshold taken from the frames being labelled (the loop's own
motion; the whole clip in :func:`detect_gait`):

* walking: *contact* is when the front foot is close to or touching the ground, *flight* when one
  leg passes the other. Primary reading: the foot ahead along the direction of travel is down or
  its lowest point (ankle or toe) is within ``near_ground_frac`` of its swing clearance (its
  largest height above the ground), *and* the feet are apart: their horizontal separation along
  the direction of travel is at least ``pass_frac`` of the step separation (the 95th percentile of
  the absolute separation). This is a window around each heel strike, from the landing to the
  moment the trailing leg starts to swing past, not the whole stance. Second reading: the feet
  apart alone (separation only).
* jogging: *flight* is both feet in the air, *contact* at least one foot on the ground. Primary
  reading: a foot down (height and speed). Second reading: a foot's lowest point within
  ``jog_ground_frac`` of its swing clearance (height only).

The root altitude (rises in flight, falls in contact) is kept for the elbow bounce of Sec. 4.2.

A loop is two full gait cycles from a left heel strike to the left heel strike two cycles later
(the paper's clips start at *left contact*). To loop seamlessly we spread the pose residual between
the loop's first frame and the frame after its last over the loop (slerp from identity to the
residual, Kovar-style drift correction, ours): the tiled loop is continuous at every seam, the
root advances by the loop's horizontal displacement per copy.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ..errors import WalkTalkError
from ..kinematics import forward_kinematics_np
from ..rotations import quat_conjugate_np, quat_multiply_np
from ..skeleton import Motion
from .body import Body, find_body
from .params import GaitParams


@dataclass(frozen=True)
class GaitInfo:
    """Per-frame gait labels of one clip. Arrays are (F,)."""

    down_l: np.ndarray
    down_r: np.ndarray
    contact: np.ndarray
    strikes_l: tuple[int, ...]
    strikes_r: tuple[int, ...]
    gait: str                      # "walk" or "jog"
    root_height: np.ndarray
    contact_alt: np.ndarray        # the second reading of the phases (:func:`contact_phases`)
    separation: np.ndarray         # left ankle ahead of the right along the direction of travel, cm


@dataclass(frozen=True)
class Loop:
    """A seamless two-cycle locomotion loop.

    motion: N frames (frame N would equal frame 0 advanced by ``advance``); advance: (3,) root
    displacement per loop copy (horizontal only); contact: (N,) contact labels; gait: walk | jog;
    source: file it came from; start: first frame in the source clip; strikes: left/right heel
    strikes relative to ``start``.
    """

    motion: Motion
    advance: np.ndarray
    contact: np.ndarray
    gait: str
    source: str
    start: int
    strikes_l: tuple[int, ...]
    strikes_r: tuple[int, ...]
    root_joint: int = 1
    root_height: np.ndarray | None = None   # (N,) hips altitude, cm (for the elbow bounce)
    contact_alt: np.ndarray | None = None   # (N,) the second reading of the phases (None = as ``contact``)

    @property
    def num_frames(self) -> int:
        return self.motion.num_frames


def _runs(mask: np.ndarray, min_len: int) -> list[tuple[int, int]]:
    """Half-open [a, b) runs of True of at least ``min_len`` frames."""
    m = np.concatenate([[False], mask.astype(bool), [False]])
    d = np.diff(m.astype(int))
    starts, ends = np.flatnonzero(d == 1), np.flatnonzero(d == -1)
    return [(int(a), int(b)) for a, b in zip(starts, ends) if b - a >= min_len]


def foot_down(height: np.ndarray, speed: np.ndarray, p: GaitParams) -> np.ndarray:
    """height, speed: (F,) of one foot point -> (F,) bool down."""
    return (height - height.min() < p.height_tol_cm) & (speed < p.speed_tol_cms)


def _horizontal_speed(x: np.ndarray, fps: float) -> np.ndarray:
    """(F, 3) -> (F,) horizontal speed, the smaller of the backward and forward differences, so a
    foot that lands (or lifts off) on frame t counts as still on that frame."""
    n = len(x)
    if n < 2:
        return np.zeros(n)
    d = np.linalg.norm(np.diff(x[:, [0, 2]], axis=0), axis=1) * fps
    back = np.r_[d[0], d]
    fwd = np.r_[d, d[-1]]
    return np.minimum(back, fwd)


STEP_PERCENTILE = 95.0  # the step separation: this percentile of the feet's absolute separation


@dataclass(frozen=True)
class FootTracks:
    """Foot kinematics of a run of frames, the input of :func:`contact_phases`. Arrays are (F,).

    low_l, low_r: height of each foot's lowest point (ankle or toe) above the ground (the lowest
    such point over the frames), cm; separation: the left ankle's lead over the right along the
    direction of travel (the hips' horizontal displacement over the frames), cm."""

    low_l: np.ndarray
    low_r: np.ndarray
    separation: np.ndarray


def foot_tracks(pos: np.ndarray, body: Body) -> FootTracks:
    """pos: (F, J, 3) joint positions (Y up, cm) -> :class:`FootTracks`."""
    low = {s: np.minimum(pos[:, body.joints[f"foot_{s}"], 1], pos[:, body.joints[f"toes_{s}"], 1]) for s in ("l", "r")}
    ground = min(low["l"].min(), low["r"].min())
    root = pos[:, body.joints["hips"]]
    travel = root[-1] - root[0]
    heading = np.array([travel[0], 0.0, travel[2]])
    heading = heading / max(np.linalg.norm(heading), 1e-9)
    sep = (pos[:, body.joints["foot_l"]] - pos[:, body.joints["foot_r"]]) @ heading
    return FootTracks(low["l"] - ground, low["r"] - ground, sep)


class ContactReadings(NamedTuple):
    """Contact labels (F,) bool (True = contact, False = flight) in the two readings of
    :func:`contact_phases`: ``contact`` (primary; synchronization uses it) and ``second``."""

    contact: np.ndarray
    second: np.ndarray


def contact_phases(tracks: FootTracks, down_l: np.ndarray, down_r: np.ndarray, gait: str,
                   p: GaitParams) -> ContactReadings:
    """Contact labels by the paper's definition (Sec. 3.1), in two readings; see the module
    docstring. ``down_l``, ``down_r``: (F,) feet down (height and speed).
    Thresholds come from ``tracks`` itself: each foot's swing clearance (its largest ``low``) and
    the step separation (the :data:`STEP_PERCENTILE` percentile of ``abs(separation)``)."""
    clear_l, clear_r = float(tracks.low_l.max()), float(tracks.low_r.max())
    if gait == "jog":
        on_ground = (tracks.low_l <= p.jog_ground_frac * clear_l) | (tracks.low_r <= p.jog_ground_frac * clear_r)
        return ContactReadings(down_l | down_r, on_ground)
    sep = tracks.separation
    step = float(np.percentile(np.abs(sep), STEP_PERCENTILE)) if len(sep) else 0.0
    apart = (np.abs(sep) >= p.pass_frac * step) & (step > 0)
    near_l = _landing(down_l, tracks.low_l <= p.near_ground_frac * clear_l)
    near_r = _landing(down_r, tracks.low_r <= p.near_ground_frac * clear_r)
    front_near = np.where(sep > 0, near_l, near_r)
    return ContactReadings(front_near & apart, apart)


def _landing(down: np.ndarray, low: np.ndarray) -> np.ndarray:
    """(F,) a foot on or close to the ground: down, or low in the run of low frames that reaches a
    down frame (landing or lifting off). A swing foot whose toe dips toward the floor mid-swing and
    rises again before it lands is not close to the ground there."""
    near = down | low
    out = np.zeros_like(near)
    for a, b in _runs(near, 1):
        if down[a:b].any():
            out[a:b] = True
    return out


def detect_gait(motion: Motion, p: GaitParams, body: Body | None = None,
                positions: np.ndarray | None = None) -> GaitInfo:
    """Foot contacts, heel strikes and contact phases of a locomotion clip (Y up, cm); the phase
    thresholds are taken from the whole clip (:func:`extract_loop` relabels a loop from its own frames)."""
    body = body or find_body(motion.skeleton, motion.name)
    pos = forward_kinematics_np(motion) if positions is None else positions
    downs = feet_down(pos, body, motion.fps, p)
    flight = ~(downs["l"] | downs["r"])
    gait = "jog" if flight.mean() >= p.jog_flight_frac else "walk"
    tracks = foot_tracks(pos, body)
    contact, alt = contact_phases(tracks, downs["l"], downs["r"], gait, p)
    strikes = {s: tuple(a for a, _ in _runs(downs[s], p.min_down_frames) if a > 0) for s in ("l", "r")}
    return GaitInfo(downs["l"], downs["r"], contact, strikes["l"], strikes["r"], gait,
                    pos[:, body.joints["hips"], 1].copy(), alt, tracks.separation)


def feet_down(pos: np.ndarray, body: Body, fps: float, p: GaitParams) -> dict:
    """Side ("l", "r") -> (F,) bool: the ankle or the toe down (:func:`foot_down`), runs shorter
    than ``p.min_down_frames`` dropped."""
    downs = {}
    for side in ("l", "r"):
        a, t = pos[:, body.joints[f"foot_{side}"]], pos[:, body.joints[f"toes_{side}"]]
        down = foot_down(a[:, 1], _horizontal_speed(a, fps), p) | foot_down(t[:, 1], _horizontal_speed(t, fps), p)
        keep = np.zeros_like(down)
        for s, e in _runs(down, p.min_down_frames):
            keep[s:e] = True
        downs[side] = keep
    return downs


def seam_correct(rotations: np.ndarray) -> np.ndarray:
    """Spread the rotation residual between frame N (the frame after the loop) and frame 0 over the loop.

    rotations: (N+1, J, 4), the loop plus the following frame -> (N, J, 4) where corrected frame
    i is slerp(I, r, i/N) q_i with r = q_0 q_N^-1, so that the virtual frame N equals frame 0.
    Float64 NumPy (runs once per loop): slerp from the identity is r's rotation angle scaled by i/N.
    """
    n = rotations.shape[0] - 1
    q = np.asarray(rotations, dtype=np.float64)
    r = quat_multiply_np(q[0], quat_conjugate_np(q[n]))
    r = np.where(r[:, :1] < 0, -r, r)  # shorter arc
    half = np.arccos(np.clip(r[:, 0], -1.0, 1.0))  # (J,)
    s = np.sin(half)
    axis = np.where(s[:, None] > 1e-12, r[:, 1:] / np.where(s > 1e-12, s, 1.0)[:, None], 0.0)
    a = np.arange(n)[:, None] / n  # (N, 1)
    corr = np.concatenate([np.cos(a * half)[..., None], np.sin(a * half)[..., None] * axis[None]], axis=-1)
    return quat_multiply_np(corr, q[:n]).astype(rotations.dtype)


def extract_loop(motion: Motion, p: GaitParams, body: Body | None = None, which: str = "middle") -> Loop:
    """Two full gait cycles from a left heel strike (paper Sec. 4); raises :class:`WalkTalkError`
    listing the strikes found when the clip holds fewer than two cycles."""
    body = body or find_body(motion.skeleton, motion.name)
    pos = forward_kinematics_np(motion)
    g = detect_gait(motion, p, body, pos)
    sl = list(g.strikes_l)
    if len(sl) < 3:
        raise WalkTalkError(f"fewer than two gait cycles: left heel strikes at frames {list(g.strikes_l)}, "
                            f"right heel strikes at frames {list(g.strikes_r)} (need three left strikes)",
                            motion.name, f"frames 0-{motion.num_frames - 1}")
    cands = [(sl[i], sl[i + 2]) for i in range(len(sl) - 2)]
    if which == "middle":
        mid = motion.num_frames / 2
        a, b = min(cands, key=lambda c: abs(0.5 * (c[0] + c[1]) - mid))
    else:
        a, b = cands[int(which)]
    n = b - a
    rot = seam_correct(motion.rotations[a:b + 1])
    tr = np.array(motion.translations[a:b], dtype=np.float64)
    # the topmost joint with moving position channels (the hips in bandai2; joint_Root is static)
    # carries the travel: it advances horizontally by its displacement over the loop, and its
    # vertical residual is spread linearly like the rotations
    moving = [j for j in range(motion.skeleton.num_joints) if np.ptp(motion.translations[a:b + 1, j], axis=0).max() > 1e-6]
    j0 = moving[0] if moving else 0
    d = motion.translations[b, j0] - motion.translations[a, j0]
    adv = np.array([d[0], 0.0, d[2]])
    tr[:, j0, 1] -= np.arange(n) / n * d[1]
    lm = dataclasses.replace(motion, rotations=rot, translations=tr, name=f"{motion.name}[{a}:{b}]")
    # the phases relabelled with thresholds from the loop's own frames
    contact, alt = contact_phases(foot_tracks(pos[a:b], body), g.down_l[a:b], g.down_r[a:b], g.gait, p)
    return Loop(lm, adv, contact, g.gait, motion.name, int(a),
                tuple(s - a for s in g.strikes_l if a <= s < b), tuple(s - a for s in g.strikes_r if a <= s < b),
                j0, g.root_height[a:b].copy(), alt)


def tile_indices(n_loop: int, n_frames: int) -> tuple[np.ndarray, np.ndarray]:
    """Frame t of a tiled loop is loop frame idx[t] in copy copies[t]."""
    t = np.arange(n_frames)
    return t % n_loop, t // n_loop


def tile_loop(loop: Loop, n_frames: int, start_offset: np.ndarray | None = None) -> Motion:
    """The loop repeated to ``n_frames`` frames; copy k is advanced by k * loop.advance."""
    idx, copies = tile_indices(loop.num_frames, n_frames)
    m = loop.motion
    rot = m.rotations[idx]
    tr = m.translations[idx].copy()
    j = loop.root_joint
    tr[:, j] += copies[:, None] * loop.advance[None]
    if start_offset is not None:
        tr[:, j] += start_offset[None]
    return dataclasses.replace(m, rotations=rot, translations=tr, name=f"{m.name}x{n_frames}")


def tile_contact(loop: Loop, n_frames: int, second: bool = False) -> np.ndarray:
    """(n_frames,) contact labels of the tiled loop: the primary reading, or (``second``) the
    second reading (:func:`contact_phases`; the primary when the loop has none)."""
    labels = loop.contact_alt if second and loop.contact_alt is not None else loop.contact
    return labels[tile_indices(loop.num_frames, n_frames)[0]]


def seam_foot_slide(motion: Motion, n_loop: int, p: GaitParams, body: Body | None = None,
                    positions: np.ndarray | None = None, window: int = 5) -> float:
    """Largest horizontal step (cm) between consecutive frames of a foot point that is down in both
    frames, over the frames within ``window`` of a loop seam (frame k*N-1 -> k*N); 0 when no seam
    lies inside the motion."""
    body = body or find_body(motion.skeleton, motion.name)
    pos = forward_kinematics_np(motion) if positions is None else positions
    n = motion.num_frames
    near = np.zeros(n, bool)          # frames t whose step t-1 -> t lies within ``window`` of a seam
    for s in range(n_loop, n, n_loop):
        near[max(1, s - window):min(n, s + window + 1)] = True
    if not near.any():
        return 0.0
    worst = 0.0
    for side in ("l", "r"):
        for key in (f"foot_{side}", f"toes_{side}"):
            x = pos[:, body.joints[key]]
            down = foot_down(x[:, 1], _horizontal_speed(x, motion.fps), p)
            both = near[1:] & down[1:] & down[:-1]
            if both.any():
                step = np.linalg.norm(np.diff(x[:, [0, 2]], axis=0), axis=1)
                worst = max(worst, float(step[both].max()))
    return worst
