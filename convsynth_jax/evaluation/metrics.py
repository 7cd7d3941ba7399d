"""Objective motion-quality metrics (the user study cannot be rerun here).

All metrics are plain float64 NumPy on global joint positions (F, J, 3) in the file's units.
"""
from __future__ import annotations

import numpy as np

from ..kinematics import forward_difference, jerk, seam_acceleration


def mean_acceleration(positions: np.ndarray, fps: float, weights: np.ndarray | None = None) -> float:
    """Mean (over frames, weighted over joints) magnitude of joint acceleration."""
    a = np.linalg.norm(forward_difference(positions, fps, 2), axis=-1)  # (F-2, J)
    return _weighted_mean(a, weights)


def mean_jerk(positions: np.ndarray, fps: float, weights: np.ndarray | None = None) -> float:
    """Mean (over frames, weighted over joints) magnitude of joint jerk (``kinematics.jerk``)."""
    j = np.linalg.norm(jerk(positions, fps), axis=-1)
    return _weighted_mean(j, weights)


def _weighted_mean(values: np.ndarray, weights: np.ndarray | None) -> float:
    if values.size == 0:
        return float("nan")
    if weights is None:
        return float(values.mean())
    w = np.asarray(weights, dtype=np.float64)
    if w.sum() <= 0:
        return float("nan")
    return float((values.mean(axis=0) * w).sum() / w.sum())


def speed_magnitudes(positions: np.ndarray, fps: float) -> np.ndarray:
    """(F-1, J) joint speed magnitudes (forward differences of positions (F, J, 3))."""
    return np.linalg.norm(forward_difference(positions, fps, 1), axis=-1)


def hellinger_distance(p: np.ndarray, q: np.ndarray) -> float:
    """Hellinger distance between two histograms (normalized here); 0 = identical, 1 = disjoint."""
    p = np.asarray(p, dtype=np.float64)
    q = np.asarray(q, dtype=np.float64)
    if p.sum() <= 0 or q.sum() <= 0:
        return float("nan")
    p = p / p.sum()
    q = q / q.sum()
    bc = np.sum(np.sqrt(p * q))
    return float(np.sqrt(max(0.0, 1.0 - bc)))


def speed_histogram_distance(positions_a: np.ndarray, positions_b: np.ndarray, fps: float,
                             bins: int = 50, max_speed: float | None = None) -> float:
    """Hellinger distance between the joint-speed histograms of two motions (shared bins)."""
    sa = speed_magnitudes(positions_a, fps).ravel()
    sb = speed_magnitudes(positions_b, fps).ravel()
    hi = max_speed if max_speed is not None else float(np.percentile(np.concatenate([sa, sb]), 99.5))
    hi = max(hi, 1e-9)
    ha, _ = np.histogram(np.clip(sa, 0, hi), bins=bins, range=(0, hi))
    hb, _ = np.histogram(np.clip(sb, 0, hi), bins=bins, range=(0, hi))
    return hellinger_distance(ha, hb)


def window_diversity(root_relative_windows: list[np.ndarray]) -> float:
    """Mean pairwise distance between synthesized windows: for each pair of windows (F, J, 3) the
    mean over common frames of the per-frame mean joint distance. Higher = more varied output."""
    ws = [np.asarray(w, dtype=np.float64) for w in root_relative_windows if w is not None and len(w)]
    if len(ws) < 2:
        return float("nan")
    dists = []
    for a in range(len(ws)):
        for b in range(a + 1, len(ws)):
            n = min(len(ws[a]), len(ws[b]))
            dists.append(float(np.linalg.norm(ws[a][:n] - ws[b][:n], axis=-1).mean()))
    return float(np.mean(dists))


def max_frame_jump(positions: np.ndarray) -> np.ndarray:
    """(F-1,) largest per-joint position change between consecutive frames."""
    d = np.linalg.norm(np.diff(np.asarray(positions, dtype=np.float64), axis=0), axis=-1)
    return d.max(axis=1) if d.size else np.zeros(0)


def root_relative_acceleration(positions: np.ndarray, fps: float) -> np.ndarray:
    """(F-2, J) joint acceleration magnitudes of positions relative to the root joint (joint 0's
    position subtracted; heading not undone); row i is output frame i + 1 (central difference):
    ``kinematics.seam_acceleration`` without its repeated first and last rows."""
    p = np.asarray(positions, dtype=np.float64)
    return seam_acceleration(p, fps)[1:-1] if p.shape[0] >= 3 else np.zeros((0,) + p.shape[1:2])


SEAM_RADIUS = 3  # frames either side of a synthetic transition that count as its seam


def seam_ratio(positions: np.ndarray, gt_positions: np.ndarray, fps: float, synthetic_at,
               radius: int = SEAM_RADIUS) -> float:
    """Largest root-relative joint acceleration within ``radius`` frames of a synthetic transition
    (output frames u with |u - t| <= radius for a transition arriving at t), divided by the largest
    root-relative acceleration of the ground-truth window anywhere. NaN without transitions (no
    seam to measure) or without ground-truth motion. Goal: <= 1 (a seam no sharper than real motion)."""
    acc = root_relative_acceleration(positions, fps)
    gt = root_relative_acceleration(gt_positions, fps)
    centres = {u for t in synthetic_at for u in range(int(t) - radius, int(t) + radius + 1)}
    rows = np.array(sorted(u - 1 for u in centres if 0 <= u - 1 < acc.shape[0]), dtype=np.int64)
    if rows.size == 0 or gt.size == 0 or gt.max() <= 0:
        return float("nan")
    return float(acc[rows].max() / gt.max())


def seam_content_ratio(clip_acc: dict, source_clip, source_frame, gt_positions: np.ndarray, fps: float,
                       synthetic_at, blend_frames: int, radius: int = SEAM_RADIUS) -> float:
    """What the source motion brings to the seams, on the scale of :func:`seam_ratio` (a diagnostic,
    ours): the largest root-relative acceleration that the played source clips have by themselves at
    the seam frames (output frames within ``radius`` of a synthetic transition; per frame the new
    source's frame and, during the ``blend_frames`` after a transition at t, the previous clip's
    continuation, clip[t - 1] at frame[t - 1] + u - t + 1), over the ground-truth window's largest.
    A window whose ``seam_ratio`` is over 1 while this is too has fast source content at its seams,
    which any blend inherits; ``seam_ratio`` above both points at the blend.

    clip_acc: clip name -> (F, J) acceleration magnitudes of the whole clip per frame (row f: frame
    f's central difference; the first and last rows repeat their neighbours), from the clip's own
    motion (:func:`clip_acceleration`). NaN as :func:`seam_ratio`."""
    gt = root_relative_acceleration(gt_positions, fps)
    T = len(source_frame)
    syn = sorted({int(t) for t in synthetic_at if 0 < int(t) < T})
    if not syn or gt.size == 0 or gt.max() <= 0:
        return float("nan")

    def acc_at(clip, frame):
        a = clip_acc[clip]
        return float(a[min(max(int(frame), 0), a.shape[0] - 1)].max())

    best = 0.0
    centres = {u for t in syn for u in range(t - radius, t + radius + 1) if 0 <= u < T}
    for u in centres:
        best = max(best, acc_at(source_clip[u], source_frame[u]))
        for t in syn:   # the previous clip's continuation, cross-faded during the blend after t
            if t <= u < t + blend_frames:
                best = max(best, acc_at(source_clip[t - 1], int(source_frame[t - 1]) + u - t + 1))
    return best / float(gt.max())


def clip_acceleration(positions: np.ndarray, fps: float) -> np.ndarray:
    """(F, J) per-frame root-relative acceleration magnitudes of a whole clip, for
    :func:`seam_content_ratio`: ``kinematics.seam_acceleration`` (the first and last frames take
    their neighbours' values)."""
    return seam_acceleration(positions, fps)
