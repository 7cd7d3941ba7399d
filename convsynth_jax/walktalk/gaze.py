"""Gaze and attention (paper Sec. 5): addresser-addressee relationships (AAR) and torso/neck yaw.

An AAR event says that ``addresser`` looks at ``addressee`` with an envelope: 0 before
``t_begin``, rising linearly to 1 at ``t_full``, 1 until ``t_release``, falling to 0 at ``t_end``.
For an event inferred from a gesture the envelope is (t_Pb, t_Sb, t_Rb, t_Re): the direction is
reached by the start of the stroke and released with the retraction (paper).

Yaw: theta_yaw is the horizontal angle from the addresser's heading to the addressee; the applied
yaw is r * theta_yaw * envelope, r uniform in [r_min, r_max] per event (paper: [0.6, 1]), split
over spine, chest, neck and head by ``joint_shares`` (ours). Lean: when the addressee is more than
``lean_distance_m`` ahead or behind, the lean joint pitches toward them by up to ``lean_max_deg``
(reached at ``lean_full_m``; ours). The yaw is clipped to +-``max_yaw_deg`` (ours: an addressee
straight behind would otherwise ask for a 180 degree neck turn). Rotations are layered on the locomotion torso as world-space
rotations at each joint: local' = G_parent^-1 R G_parent local, so joint j's global rotation
becomes R_{cumulative} G_j.

AAR modes: ``inferred`` (the gesturer addresses the nearest other character), ``random`` (the
gesturer addresses a random other character), ``scripted`` (events given by the user),
``statistics`` (alternating gaze-at / gaze-away segments with durations drawn from (mean, sd) per
behaviour; a behaviour chosen again past mean + sd total is forced to switch; the durations are
OURS, the paper's ground-truth values are not published).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import WalkTalkError
from ..kinematics import global_transforms_np
from ..rig import find_role
from ..rotations import matrix_to_quat_np, quat_to_matrix_np
from ..skeleton import Motion
from .params import GazeParams


@dataclass(frozen=True)
class AAREvent:
    addresser: str
    addressee: str
    t_begin: float
    t_full: float
    t_release: float
    t_end: float


def validate_events(events, characters) -> None:
    chars = set(characters)
    for i, e in enumerate(events):
        where = f"AAR event {i} ({e.t_begin:.2f}-{e.t_end:.2f} s)"
        if e.addresser == e.addressee:
            raise WalkTalkError(f"character {e.addresser!r} cannot address itself", where=where)
        for who in (e.addresser, e.addressee):
            if who not in chars:
                raise WalkTalkError(f"unknown character {who!r}; characters are {sorted(chars)}", where=where)
        if not e.t_begin <= e.t_full <= e.t_release <= e.t_end:
            raise WalkTalkError("AAR times out of order (need t_begin <= t_full <= t_release <= t_end)", where=where)


def envelope(t: np.ndarray, e: AAREvent) -> np.ndarray:
    up = np.clip((t - e.t_begin) / max(e.t_full - e.t_begin, 1e-9), 0, 1)
    down = np.clip((e.t_end - t) / max(e.t_end - e.t_release, 1e-9), 0, 1)
    return np.where((t < e.t_begin) | (t > e.t_end), 0.0, np.minimum(up, down))


def events_from_gestures(gestures: list[dict], positions: dict, mode: str, rng: np.random.Generator,
                         fps: float) -> list[AAREvent]:
    """gestures: dicts with character, t_prep_begin, t_stroke_begin, t_retraction_begin,
    t_retraction_end; positions: character -> (T, 3) root positions. ``inferred`` picks the
    nearest other character at the stroke, ``random`` a random other one."""
    out = []
    names = list(positions)
    for g in gestures:
        others = [c for c in names if c != g["character"]]
        if not others:
            continue
        if mode == "random":
            who = others[int(rng.integers(len(others)))]
        else:
            f = min(int(g["t_stroke_begin"] * fps), len(positions[g["character"]]) - 1)
            me = positions[g["character"]][f]
            who = min(others, key=lambda c: float(np.linalg.norm(positions[c][f] - me)))
        out.append(AAREvent(g["character"], who, g["t_prep_begin"], g["t_stroke_begin"], g["t_retraction_begin"],
                            g["t_retraction_end"]))
    return out


def statistics_events(characters, duration: float, p: GazeParams, rng: np.random.Generator,
                      ramp_s: float = 0.3) -> list[AAREvent]:
    """Gaze-at / gaze-away alternation per character (Sec. 5, "Synthesize AAR from ground truth")."""
    out = []
    for c in characters:
        others = [o for o in characters if o != c]
        if not others:
            continue
        t, kind, run_total = 0.0, "away", 0.0
        while t < duration:
            nxt = "at" if rng.uniform() < 0.5 else "away"
            mean, sd = p.gaze_at_s if nxt == "at" else p.gaze_away_s
            if nxt == kind and run_total > mean + sd:
                nxt = "away" if kind == "at" else "at"
                mean, sd = p.gaze_at_s if nxt == "at" else p.gaze_away_s
            d = max(2 * ramp_s, float(rng.normal(mean, sd)))
            run_total = run_total + d if nxt == kind else d
            kind = nxt
            if kind == "at":
                who = others[int(rng.integers(len(others)))]
                out.append(AAREvent(c, who, t, t + ramp_s, t + d - ramp_s, t + d))
            t += d
    return out


def _yaw_matrix(a):
    c, s = np.cos(a), np.sin(a)
    z, o = np.zeros_like(a), np.ones_like(a)
    return np.stack([np.stack([c, z, s], -1), np.stack([z, o, z], -1), np.stack([-s, z, c], -1)], -2)


def _axis_matrix(axis, a):
    """Rodrigues: (T, 3) unit axes, (T,) angles -> (T, 3, 3)."""
    x, y, z = axis[:, 0], axis[:, 1], axis[:, 2]
    c, s = np.cos(a), np.sin(a)
    C = 1 - c
    return np.stack([np.stack([c + x * x * C, x * y * C - z * s, x * z * C + y * s], -1),
                     np.stack([y * x * C + z * s, c + y * y * C, y * z * C - x * s], -1),
                     np.stack([z * x * C - y * s, z * y * C + x * s, c + z * z * C], -1)], -2)


def heading_of(root: np.ndarray, fps: float, window_s: float = 1.0) -> np.ndarray:
    """(T, 3) root positions -> (T, 3) unit horizontal travel direction (central difference over
    ``window_s``; +Z where the root does not move)."""
    k = max(1, int(window_s * fps / 2))
    idx = np.arange(len(root))
    d = root[np.minimum(idx + k, len(root) - 1)] - root[np.maximum(idx - k, 0)]
    d[:, 1] = 0
    n = np.linalg.norm(d, axis=1, keepdims=True)
    return np.where(n > 1e-6, d / np.maximum(n, 1e-9), np.array([0.0, 0.0, 1.0]))


def gaze_angles(me: np.ndarray, heading: np.ndarray, other: np.ndarray):
    """theta_yaw (T,) radians (positive = about +Y, turning +Z toward +X) and the signed forward
    distance (T,) of ``other`` along ``heading``, in the file's units."""
    d = other - me
    d[:, 1] = 0
    theta = np.arctan2(heading[:, 2] * d[:, 0] - heading[:, 0] * d[:, 2], heading[:, 0] * d[:, 0] + heading[:, 2] * d[:, 2])
    return theta, np.sum(d * heading, axis=1)


def apply_gaze(motion: Motion, character: str, events: list[AAREvent], others: dict, p: GazeParams,
               rng: np.random.Generator, units_per_m: float = 100.0) -> tuple[Motion, np.ndarray]:
    """Layer the AAR yaw and lean of ``character`` onto ``motion``'s torso. others: name -> (T, 3)
    root positions of the other characters. Returns (motion, applied total yaw (T,) radians)."""
    sk = motion.skeleton
    T = motion.num_frames
    t = np.arange(T) / motion.fps
    pos, glob = global_transforms_np(motion)   # of the un-gazed motion
    hips = find_role(sk, "hips")
    me = pos[:, hips]
    heading = heading_of(me, motion.fps)
    yaw = np.zeros(T)
    lean = np.zeros(T)
    for e in events:
        if e.addresser != character:
            continue
        if e.addressee not in others:
            raise WalkTalkError(f"addressee {e.addressee!r} has no position track", where=f"AAR {e}")
        w = envelope(t, e)
        if not w.any():
            continue
        r = float(rng.uniform(p.r_min, p.r_max))
        theta, fwd = gaze_angles(me, heading, others[e.addressee])
        lim = np.radians(p.max_yaw_deg)
        yaw += w * np.clip(r * theta, -lim, lim)
        over = (np.abs(fwd) / units_per_m - p.lean_distance_m) / max(p.lean_full_m - p.lean_distance_m, 1e-9)
        lean += w * np.sign(fwd) * np.radians(p.lean_max_deg) * np.clip(over, 0, 1)
    mats = quat_to_matrix_np(motion.rotations)
    rot = np.array(motion.rotations, dtype=np.float64)
    up = np.array([0.0, 1.0, 0.0])
    lean_axis = np.cross(np.broadcast_to(up, heading.shape), heading)
    lean_joint = sk.find(f"^{p.lean_joint}$")
    for name, share in p.joint_shares.items():
        j = sk.find(f"^{name}$")
        if j is None:
            raise WalkTalkError(f"gaze joint {name!r} not in the skeleton {list(sk.names)}", motion.name)
        R = _yaw_matrix(share * yaw)
        if j == lean_joint:
            R = _axis_matrix(lean_axis, lean) @ R
        gp = glob[:, sk.parents[j]]
        local = np.swapaxes(gp, -1, -2) @ R @ gp @ mats[:, j]
        rot[:, j] = matrix_to_quat_np(local)
    if lean_joint is not None and p.lean_joint not in p.joint_shares:
        gp = glob[:, sk.parents[lean_joint]]
        rot[:, lean_joint] = matrix_to_quat_np(np.swapaxes(gp, -1, -2) @ _axis_matrix(lean_axis, lean) @ gp
                                             @ mats[:, lean_joint])
    from dataclasses import replace

    return replace(motion, rotations=rot), yaw
