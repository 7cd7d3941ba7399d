"""Rendering one participant's motion: idle (posture, drift, breathing, noise), planted gestures and
nods, posture shifts, sensor noise and marker-swap glitches; BVH Euler angles to quaternions."""
from __future__ import annotations

import numpy as np

from ...easing import smoothstep
from ...rotations import quat_multiply_np, yaw_to_quat_np
from ...skeleton import Motion
from ..skeleton_seated import INDEX, NAMES, SEAT_HEIGHT, base_pose_degrees, seated_skeleton
from .config import ROLES


def _smooth_noise(rng, n, fps, seconds, sd):
    """Low-pass Gaussian noise with a correlation time of about ``seconds``."""
    x = rng.normal(0, 1, n + int(4 * seconds * fps))
    k = max(1, int(seconds * fps))
    ker = np.hanning(2 * k + 1)
    y = np.convolve(x, ker / ker.sum(), mode="same")[: n]
    return sd * y / max(y.std(), 1e-9)


def _bump(t, start, end):
    """Smooth 0 -> 1 -> 0 profile over [start, end] (preparation, hold around the middle, retraction)."""
    x = np.clip((t - start) / max(end - start, 1e-3), 0, 1)
    return np.sin(np.pi * x) ** 2


POSTURE_JOINTS = ("Spine", "Spine1", "Neck", "Head", "LeftArm", "RightArm", "LeftForeArm", "RightForeArm",
                  "LeftHand", "RightHand")


def _envelope(t: np.ndarray, ev: dict) -> np.ndarray:
    """Gesture profile on [start, end): from ``hold_start`` (0 = rest) up to 1 at the middle, down to
    ``hold_end`` (levels relative to the event's amplitude; both 0 unless coarticulated), 0 outside.
    Without holds it is ``_bump``."""
    s, e = ev["start"], ev["end"]
    m = 0.5 * (s + e)
    h0 = ev.get("hold_start", 0.0) / ev["amp"]
    h1 = ev.get("hold_end", 0.0) / ev["amp"]
    rise = h0 + (1 - h0) * np.sin(0.5 * np.pi * np.clip((t - s) / max(m - s, 1e-3), 0, 1)) ** 2
    fall = h1 + (1 - h1) * np.sin(0.5 * np.pi * np.clip((e - t) / max(e - m, 1e-3), 0, 1)) ** 2
    return np.where(t < m, rise, fall) * ((t >= s) & (t < e))


def _posture_offsets(rng, n: int, fps: float, shifts: list[float], session_sd: float, shift_sd: float,
                     shift_seconds) -> np.ndarray:
    """(F, len(POSTURE_JOINTS), 3) degrees: the session's posture offset, replaced at each time in
    ``shifts`` by a new one (N(0, shift_sd) around the session's) over ``shift_seconds`` (smooth step)."""
    t = np.arange(n) / fps
    base = rng.normal(0, session_sd, (len(POSTURE_JOINTS), 3))
    off = np.broadcast_to(base, (n, len(POSTURE_JOINTS), 3)).copy()
    if shift_sd <= 0:
        return off
    cur = base
    for tau in shifts:
        new = base + rng.normal(0, shift_sd, base.shape)
        d = rng.uniform(*shift_seconds)
        x = np.clip((t - tau) / d, 0, 1)
        w = smoothstep(x)[:, None, None]
        sel = t >= tau
        off[sel] = (cur + w * (new - cur))[sel]
        cur = new
    return off


GLITCH_JOINTS = ("LeftArm", "RightArm", "LeftForeArm", "RightForeArm", "LeftHand", "RightHand", "Neck", "Head")


def _glitches(rng, n: int, fps: float, per_minute: float, frames) -> list[dict]:
    """Marker-swap glitches of one participant: a Poisson number (``per_minute``) of few-frame
    artefacts, each either a ``flip`` (a forearm twists 90-180 degrees about its long axis, as when
    two markers of the segment swap labels) or a ``jump`` (one joint's rotation jumps 12-30 degrees
    about one axis, as when the solver snaps to a wrong marker). Rows: kind, joint, channel (0..2 of
    Z, X, Y), degrees, start_frame, end_frame (exclusive)."""
    count = rng.poisson(per_minute * n / fps / 60.0)
    out = []
    for _ in range(count):
        length = int(rng.integers(frames[0], frames[1] + 1))
        start = int(rng.integers(1, max(2, n - length - 1)))
        if rng.random() < 0.5:
            joint = ("LeftForeArm", "RightForeArm")[rng.integers(2)]
            out.append({"kind": "flip", "joint": joint, "channel": 2,
                        "degrees": float(rng.choice([-1, 1]) * rng.uniform(90, 180))})
        else:
            out.append({"kind": "jump", "joint": GLITCH_JOINTS[rng.integers(len(GLITCH_JOINTS))],
                        "channel": int(rng.integers(3)), "degrees": float(rng.choice([-1, 1]) * rng.uniform(12, 30))})
        out[-1].update(start_frame=start, end_frame=min(n, start + length))
    return sorted(out, key=lambda g: g["start_frame"])


def _zxy_deg_to_quat(euler: np.ndarray) -> np.ndarray:
    """(..., 3) BVH Euler angles in degrees, channel order Z X Y (intrinsic, Z outermost) -> (..., 4)
    (w, x, y, z) quaternions qz * qx * qy: the generator's fast path (about 30 times faster than
    SciPy's ``from_euler``, which ``rotations.euler_deg_to_quat_np`` uses and a test compares with)."""
    h = np.deg2rad(np.asarray(euler, np.float64)) / 2
    c, s = np.cos(h), np.sin(h)
    cz, cx, cy = c[..., 0], c[..., 1], c[..., 2]
    sz, sx, sy = s[..., 0], s[..., 1], s[..., 2]
    # qz * qx = (cz cx, cz sx, sz sx, sz cx), then times qy = (cy, 0, sy, 0)
    w, x, y, z = cz * cx, cz * sx, sz * sx, sz * cx
    return np.stack([w * cy - y * sy, x * cy - z * sy, w * sy + y * cy, z * cy + x * sy], axis=-1)


def _motion(rng, role: str, events: list[dict], n: int, fps: float, energy: float, scale: float,
            cfg: dict, shifts: list[float] = ()) -> tuple[Motion, list[dict]]:
    """The participant's motion and its glitches (see ``_glitches``)."""
    skel = seated_skeleton(scale)
    t = np.arange(n) / fps
    # streams of their own: the number of posture shifts (which follows the planted movements) does
    # not change the idle motion, the noise or the glitches
    posture_rng, glitch_rng, rng = (np.random.default_rng(rng.integers(2 ** 63)) for _ in range(3))
    euler = np.broadcast_to(base_pose_degrees(), (n, len(NAMES), 3)).copy()  # (F, J, [Z, X, Y])
    # people sit differently from one conversation to the next, shift their posture at their turns,
    # and drift slowly
    off = _posture_offsets(posture_rng, n, fps, list(shifts), cfg["posture_sd"], cfg["posture_shift_sd"],
                           cfg["posture_shift_seconds"])
    for i, j in enumerate(POSTURE_JOINTS):
        euler[:, INDEX[j]] += off[:, i]
        for c in range(3):
            euler[:, INDEX[j], c] += _smooth_noise(rng, n, fps, 10.0, cfg["drift_sd"])
    # idle: breathing on the spine chain, slow posture drift, small noise everywhere
    breath = np.sin(2 * np.pi * t / rng.uniform(3.5, 4.5) + rng.uniform(0, 6.3))
    for j, a in (("Spine", 0.8), ("Spine1", 0.6), ("Spine2", 0.5)):
        euler[:, INDEX[j], 1] += a * breath
    for j in POSTURE_JOINTS[:8]:
        for c in range(3):
            euler[:, INDEX[j], c] += _smooth_noise(rng, n, fps, 2.0, 0.6)
    euler += rng.normal(0, cfg["sensor_noise_deg"], euler.shape)
    for ev in events:
        s, p, e, amp = ev["start"], ev["peak"], ev["end"], ev["amp"] * energy
        beat = np.exp(-0.5 * ((t - p) / 0.09) ** 2) * (np.abs(t - p) < 0.4)
        if ev["kind"] in ("LH", "RH"):
            b = _envelope(t, ev)
            side = "Left" if ev["kind"] == "LH" else "Right"
            sgn = 1.0 if side == "Left" else -1.0
            euler[:, INDEX[f"{side}Arm"], 1] -= amp * (22.0 * b + 6.0 * beat)
            euler[:, INDEX[f"{side}Arm"], 0] += sgn * amp * ev["spread"] * b
            euler[:, INDEX[f"{side}ForeArm"], 1] -= amp * (18.0 * b + 10.0 * beat)
            euler[:, INDEX[f"{side}Hand"], 1] += amp * 12.0 * beat
        else:  # nod: head pitch oscillation, 1-3 cycles, with a little neck
            cyc = ev["cycles"]
            x = np.clip((t - s) / max(e - s, 1e-3), 0, 1)
            osc = np.sin(2 * np.pi * cyc * x) * np.sin(np.pi * x) * ((t >= s) & (t <= e))
            euler[:, INDEX["Head"], 1] += amp * 11.0 * osc
            euler[:, INDEX["Neck"], 1] += amp * 3.0 * osc
    glitches = _glitches(glitch_rng, n, fps, cfg["glitches_per_minute"], cfg["glitch_frames"])
    for g in glitches:
        euler[g["start_frame"]:g["end_frame"], INDEX[g["joint"]], g["channel"]] += g["degrees"]
    quats = _zxy_deg_to_quat(euler)
    trans = np.broadcast_to(skel.offsets, (n, len(NAMES), 3)).copy()
    z0 = -60.0 if role == ROLES[0] else 60.0
    trans[:, 0] = (0.0, SEAT_HEIGHT, z0)
    trans[:, 0, 0] += _smooth_noise(rng, n, fps, 6.0, 0.8)
    trans[:, 0, 2] += _smooth_noise(rng, n, fps, 6.0, 0.8)
    trans[:, 0, 1] += 0.3 * breath
    if cfg["sensor_noise_cm"] > 0:
        trans[:, 0] += rng.normal(0, cfg["sensor_noise_cm"], (n, 3))
    if role == ROLES[1]:  # the interlocutor faces the other way (-Z)
        quats[:, 0] = quat_multiply_np(yaw_to_quat_np(np.pi), quats[:, 0])
    return Motion(skel, quats, trans, float(fps), role), glitches
