"""Measures over sets of windows of root-relative joint positions (each (T, P, 3)), as the
naturalness analyses compare a system with the ground truth of the same windows: raw-window FGD
features, the per-joint pose spread and its ratio, single poses for a pose-only Frechet distance,
and the FGD split into its mean and covariance terms."""
from __future__ import annotations

import numpy as np

from .fgd import frechet_distance, gaussian_stats, raw_window_features
from .params import FGDParams


def raw_features(rels, fp: FGDParams | None = None) -> np.ndarray:
    """Raw-window FGD features of every window of ``rels``, stacked (``fgd.raw_window_features``)."""
    fp = fp or FGDParams()
    return np.concatenate([raw_window_features(r, fp.raw_window_frames, fp.raw_frame_step) for r in rels])


def joint_std(rels) -> np.ndarray:
    """(P,) each joint's positional spread over all frames of ``rels``: sqrt of its summed per-axis variance."""
    x = np.concatenate(rels).astype(np.float64)
    return np.sqrt(x.var(axis=0).sum(axis=-1))


def pose_std_ratio(rels_sys, rels_gt) -> float:
    """Median over joints of the system's spread over the ground truth's."""
    return float(np.median(joint_std(rels_sys) / np.maximum(joint_std(rels_gt), 1e-9)))


def single_poses(rels, step: int = 3) -> np.ndarray:
    """(N, 3 P) single poses (every ``step``-th frame): a Frechet distance over them compares what poses
    are shown, not how they move."""
    return np.concatenate([r[::step].reshape(len(r[::step]), -1) for r in rels]).astype(np.float64)


def fgd_split(rels_sys, rels_gt, fp: FGDParams | None = None) -> dict:
    """The raw FGD and its two terms: the squared distance of the feature means (``fgd_mean_term``) and
    the rest, from the covariances (``fgd_cov_term``); the system's total feature variance as a share of
    the ground truth's; the largest per-joint distance of the mean poses (position units)."""
    ms, ss = gaussian_stats(raw_features(rels_sys, fp))
    mg, sg = gaussian_stats(raw_features(rels_gt, fp))
    total = frechet_distance(ms, ss, mg, sg)
    mean_term = float((ms - mg) @ (ms - mg))
    pose_s, pose_g = np.concatenate(rels_sys).mean(axis=0), np.concatenate(rels_gt).mean(axis=0)
    return {"fgd_raw": total, "fgd_mean_term": mean_term, "fgd_cov_term": total - mean_term,
            "total_variance_ratio": float(np.trace(ss) / np.trace(sg)),
            "mean_pose_offset_max_cm": float(np.linalg.norm(pose_s - pose_g, axis=-1).max())}
