"""Synthetic clips with planted truth for tests and benchmarks (bandai2 joint names, cm, Y up).

* :func:`synthetic_jog`: feet are placed directly through their position channels (every joint
  of a bandai2 skeleton has 6 channels), so contacts are known exactly: the left foot is down for
  cycle frames 0..round(stance P), the right half a cycle later; heel strikes at k*P and (k+0.5)*P;
  arms swing sinusoidally; the root altitude is h0 + bounce * cos(4 pi t / P).
* :func:`synthetic_walk`: a walk placed the same way, with double support: each foot is down for
  cycle frames 0..round(duty P), the left from cycle frame 0 (heel strikes at k*P and (k+0.5)*P); the swing
  foot's lowest point rises to ``swing_height`` and it passes the stance foot once per step
  (``truth["passing"]``: the first frame the swing ankle is ahead of the stance ankle).
* :func:`synthetic_gesture`: a standing clip whose right (or both) upper arm rotates by a planted
  profile: rest, smooth rise, hold (optionally with oscillating peaks), smooth return.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from ..easing import smoothstep
from ..skeleton import Motion, Skeleton

NAMES = ("joint_Root", "Hips", "Spine", "Chest", "Neck", "Head", "Shoulder_L", "UpperArm_L", "LowerArm_L",
         "Hand_L", "Shoulder_R", "UpperArm_R", "LowerArm_R", "Hand_R", "UpperLeg_L", "LowerLeg_L", "Foot_L",
         "Toes_L", "UpperLeg_R", "LowerLeg_R", "Foot_R", "Toes_R")
PARENTS = (-1, 0, 1, 2, 3, 4, 3, 6, 7, 8, 3, 10, 11, 12, 1, 14, 15, 16, 1, 18, 19, 20)
OFFSETS = np.array([
    [0, 0, 0], [0, 90, 0], [0, 10, 0], [0, 15, 0], [0, 20, 0], [0, 8, 0],
    [5, 15, 0], [12, 0, 0], [28, 0, 0], [25, 0, 0],
    [-5, 15, 0], [-12, 0, 0], [-28, 0, 0], [-25, 0, 0],
    [9, 0, 0], [0, -40, 0], [0, -40, 0], [0, -7, 10],
    [-9, 0, 0], [0, -40, 0], [0, -40, 0], [0, -7, 10]], dtype=np.float64)
CHANNELS = ("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")


def skeleton() -> Skeleton:
    return Skeleton(NAMES, PARENTS, OFFSETS.copy(), tuple(CHANNELS for _ in NAMES),
                    tuple((j, (0.0, 0.0, 0.0)) for j in (5, 9, 13, 17, 21)))


def _zxy(angles_deg: np.ndarray) -> np.ndarray:
    """(F, 3) ZXY degrees -> (F, 4) (w, x, y, z)."""
    q = Rotation.from_euler("ZXY", angles_deg, degrees=True).as_quat()
    return q[:, [3, 0, 1, 2]]


def _blank(n: int):
    rot = np.zeros((n, len(NAMES), 4))
    rot[..., 0] = 1.0
    tr = np.broadcast_to(OFFSETS, (n, len(NAMES), 3)).copy()
    # arms hang down: upper arms rotated 80 degrees about Z
    rot[:, 7] = _zxy(np.tile([-80.0, 0, 0], (n, 1)))
    rot[:, 11] = _zxy(np.tile([80.0, 0, 0], (n, 1)))
    return rot, tr


def synthetic_jog(periods: float = 3.0, period: int = 30, stance: float = 0.4, speed_cm_per_frame: float = 10.0,
                  swing_height: float = 30.0, bounce: float = 5.0, arm_swing_deg: float = 20.0,
                  elbow_mean_deg: float = 60.0, elbow_amp_deg: float = 10.0, fps: float = 30.0,
                  start_phase: float = 0.0) -> tuple[Motion, dict]:
    """A jog with planted contacts. Returns (motion, truth) where truth has ``down_l``, ``down_r``,
    ``contact`` (F,) and ``strikes_l``, ``strikes_r``."""
    n = round(periods * period)
    t = np.arange(n) + round(start_phase * period)
    rot, tr = _blank(n)
    hips = np.stack([np.zeros(n), 90.0 + bounce * np.cos(4 * np.pi * t / period), speed_cm_per_frame * t], 1)
    tr[:, 1] = hips
    truth = {}
    stride = speed_cm_per_frame * period
    st = round(stance * period)          # last stance frame index within a cycle
    half = period // 2
    ti = np.arange(n) + round(start_phase * period)
    for side, off, leg, foot in (("l", 0, 14, 16), ("r", half, 18, 20)):
        idx = (ti - off) % period                 # frame within this foot's cycle
        k = (ti - off) // period
        s = np.where(idx <= st, 0.0, (idx - st) / (period - st))
        down = idx <= st
        z = stride * k + s * stride + speed_cm_per_frame * (off + 0.5 * st)
        y = swing_height * np.sin(np.pi * s)
        world = np.stack([np.full(n, OFFSETS[leg, 0]), 7.0 + y, z], 1)
        # Foot local translation = world - (hips + leg offsets); lower-body rotations are identity
        tr[:, foot] = world - hips - OFFSETS[leg] - OFFSETS[leg + 1]
        truth[f"down_{side}"] = down
        truth[f"strikes_{side}"] = tuple(int(i) for i in np.flatnonzero(down[1:] & ~down[:-1]) + 1)
    truth["contact"] = truth["down_l"] | truth["down_r"]
    ang = 2 * np.pi * t / period
    rot[:, 7] = _zxy(np.stack([-80 + np.zeros(n), np.zeros(n), arm_swing_deg * np.sin(ang)], 1))
    rot[:, 11] = _zxy(np.stack([80 + np.zeros(n), np.zeros(n), arm_swing_deg * np.sin(ang + np.pi)], 1))
    rot[:, 8] = _zxy(np.stack([np.zeros(n), np.zeros(n), elbow_mean_deg + elbow_amp_deg * np.sin(ang)], 1))
    rot[:, 12] = _zxy(np.stack([np.zeros(n), np.zeros(n), -elbow_mean_deg - elbow_amp_deg * np.sin(ang + np.pi)], 1))
    truth["hips_height"] = hips[:, 1]
    return Motion(skeleton(), rot, tr, fps, "synthetic_jog"), truth


def synthetic_walk(periods: float = 3.0, period: int = 32, duty: float = 0.6, speed_cm_per_frame: float = 4.0,
                   swing_height: float = 8.0, fps: float = 30.0) -> tuple[Motion, dict]:
    """A walk with planted heel strikes, double support and leg passing. Returns (motion, truth)
    with ``down_l``, ``down_r`` (F,) bool, ``strikes_l``, ``strikes_r`` and ``passing`` (frames)."""
    n = round(periods * period)
    t = np.arange(n, dtype=np.float64)
    rot, tr = _blank(n)
    v = speed_cm_per_frame
    hips = np.stack([np.zeros(n), np.full(n, 90.0), v * t], 1)
    tr[:, 1] = hips
    stance = round(duty * period)              # last stance frame of a cycle
    truth, z = {}, {}
    for side, off, leg, foot in (("l", 0.0, 14, 16), ("r", period / 2, 18, 20)):
        k = np.floor((t - off) / period)
        strike = k * period + off                  # the last heel strike of this foot
        idx = t - strike                           # frames since it
        s = np.clip((idx - stance) / (period - stance), 0.0, 1.0)   # swing progress
        land = v * strike + 0.5 * v * stance       # the foot lands half a stance ahead of the hips
        z[side] = land + _smooth(s) * v * period
        y = swing_height * np.sin(np.pi * s)
        world = np.stack([np.full(n, OFFSETS[leg, 0]), 7.0 + y, z[side]], 1)
        tr[:, foot] = world - hips - OFFSETS[leg] - OFFSETS[leg + 1]
        down = idx <= stance
        truth[f"down_{side}"] = down
        truth[f"strikes_{side}"] = tuple(int(i) for i in np.flatnonzero(down[1:] & ~down[:-1]) + 1)
    ahead = z["l"] > z["r"]
    truth["passing"] = tuple(int(i) for i in np.flatnonzero(ahead[1:] != ahead[:-1]) + 1)
    return Motion(skeleton(), rot, tr, fps, "synthetic_walk"), truth


def _smooth(x):
    return smoothstep(np.clip(x, 0.0, 1.0))


def synthetic_gesture(n: int = 70, rise=(10, 25), fall=(40, 55), amp_deg: float = 90.0, sides: str = "r",
                      oscillations: int = 0, osc_amp_deg: float = 25.0, travel_cm: float = 0.0,
                      fps: float = 30.0) -> Motion:
    """A standing gesture: the upper arm(s) lift by ``amp_deg`` (smooth rise over ``rise`` frames,
    hold, smooth fall over ``fall``); ``oscillations`` > 0 adds a side-to-side wave during the hold
    (several stroke peaks); ``travel_cm`` makes the root walk away (an invalid gesture clip)."""
    t = np.arange(n, dtype=np.float64)
    prof = _smooth((t - rise[0]) / (rise[1] - rise[0])) * (1 - _smooth((t - fall[0]) / (fall[1] - fall[0])))
    rot, tr = _blank(n)
    tr[:, 1, 2] = travel_cm * t / max(n - 1, 1)
    wave = np.zeros(n)
    if oscillations:
        hold = (t >= rise[1]) & (t <= fall[0])
        wave[hold] = osc_amp_deg * np.sin(2 * np.pi * oscillations * (t[hold] - rise[1]) / (fall[0] - rise[1]))
    for side, j, sign in (("l", 7, -1.0), ("r", 11, 1.0)):
        if side in sides or sides == "both":
            rot[:, j] = _zxy(np.stack([sign * (80 - amp_deg * prof), wave * prof, np.zeros(n)], 1))
    return Motion(skeleton(), rot, tr, fps, f"synthetic_gesture_{sides}")
