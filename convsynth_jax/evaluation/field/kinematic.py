"""GENEA numerical evaluations of motion statistics (Kucherenko et al., GENEA Challenge 2020/2022
``genea_numerical_evaluations``): average jerk and acceleration, histograms of moving distance and
the Hellinger distance between them. Float64 NumPy; positions ``(frames, joints, 3)`` in the BVH's
units, fps frames per second.
"""
from __future__ import annotations

import numpy as np

from ...kinematics import forward_difference
from .params import HistogramParams

# A frame is still when the mean speed of the joints looked at is below this many units per second
# (2 cm/s on the synthetic corpus, whose units are centimetres): the one still-frame definition of
# the package (``still_frames``), used by the naturalness analysis and the realization's options.
STILL_SPEED = 2.0


def moving_distance(positions: np.ndarray, fps: float, order: int) -> np.ndarray:
    """(F - order, J) norm of each joint's order-th time derivative (``kinematics.forward_difference``, the
    project's one definition): speed (order 1, units/s), acceleration (2, units/s^2), jerk (3, units/s^3)."""
    return np.linalg.norm(forward_difference(positions, fps, order), axis=-1)


def average_derivative(positions: np.ndarray, fps: float, order: int) -> float:
    """GENEA's average jerk (order 3) or acceleration (order 2): the order-th derivative's norm per
    joint, mean over frames, then mean over joints. NaN for a window shorter than order + 1 frames."""
    m = moving_distance(positions, fps, order)
    if m.size == 0:
        return float("nan")
    return float(m.mean(axis=0).mean())


def mean_joint_speed(positions: np.ndarray, fps: float) -> np.ndarray:
    """(F,) mean over joints of each frame's speed, units/s: GENEA's moving distance (``moving_distance``,
    order 1) of the step to the next frame (the last frame: of the step into it). positions (F, J, 3),
    at least two frames."""
    p = np.asarray(positions, np.float64)
    if p.ndim != 3 or p.shape[-1] != 3:
        raise ValueError(f"a joint speed needs positions of shape (frames, joints, 3), got {p.shape}")
    if len(p) < 2:
        raise ValueError(f"a joint speed needs at least two frames, got {len(p)}")
    v = moving_distance(p, fps, 1).mean(axis=1)
    return np.concatenate([v, v[-1:]])


def still_frames(positions: np.ndarray, fps: float, threshold: float = STILL_SPEED) -> np.ndarray:
    """(F,) bool: frames whose mean joint speed (:func:`mean_joint_speed`) is below ``threshold``
    units/s. Steps to the next frame, not central differences: those would average away the
    frame-to-frame tremor of recorded motion and call a quarter of the synthetic corpus's recorded
    frames still; these steps call 0.2-0.4% of them still. A window shorter than two frames has no
    speed and no still frame."""
    p = np.asarray(positions, np.float64)
    if p.ndim != 3 or p.shape[-1] != 3:
        raise ValueError(f"still_frames needs positions of shape (frames, joints, 3), got {p.shape}")
    if len(p) < 2:
        return np.zeros(len(p), bool)
    return mean_joint_speed(p, fps) < float(threshold)


def average_jerk(positions: np.ndarray, fps: float) -> float:
    return average_derivative(positions, fps, 3)


def average_acceleration(positions: np.ndarray, fps: float) -> float:
    return average_derivative(positions, fps, 2)


def histogram(values: np.ndarray, bin_width: float, max_value: float) -> np.ndarray:
    """Counts of ``values`` (any shape: every joint pooled, GENEA's sum over joints) in bins
    [k w, (k + 1) w) for k < ceil(max / w), plus a last overflow bin for values >= the last edge."""
    v = np.asarray(values, dtype=np.float64).ravel()
    nbins = int(np.ceil(max_value / bin_width - 1e-9))
    idx = np.floor(v / bin_width).astype(np.int64)
    idx = np.clip(idx, 0, nbins)   # negative cannot happen for norms; >= nbins -> overflow bin
    return np.bincount(idx, minlength=nbins + 1).astype(np.float64)


def hellinger(p: np.ndarray, q: np.ndarray) -> float:
    """Hellinger distance sqrt(1 - sum_k sqrt(p_k q_k)) of two histograms normalised to sum 1 (in
    [0, 1]; 0 for identical distributions). NaN when either is empty."""
    p, q = np.asarray(p, np.float64), np.asarray(q, np.float64)
    if p.sum() <= 0 or q.sum() <= 0:
        return float("nan")
    bc = np.sum(np.sqrt(p / p.sum() * q / q.sum()))
    gap = 1.0 - bc
    return float(np.sqrt(gap)) if gap > 1e-12 else 0.0   # round-off of identical histograms is 0


def motion_histograms(positions: np.ndarray, fps: float, params: HistogramParams) -> dict:
    """{"speed": counts, "acceleration": counts} of one window, every joint pooled."""
    return {"speed": histogram(moving_distance(positions, fps, 1), params.speed_bin_width, params.speed_max),
            "acceleration": histogram(moving_distance(positions, fps, 2), params.acceleration_bin_width,
                                      params.acceleration_max)}
