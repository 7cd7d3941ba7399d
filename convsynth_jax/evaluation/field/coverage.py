"""L1 diversity (EMAGE) and gesture area coverage.

L1 diversity of one window: the mean over frames of the L1 distance (summed over coordinates) of
the root-relative pose from the window's mean pose; the set's value is the mean over windows
(EMAGE accumulates the same sums over its test sequences).

Gesture area coverage (GAC): the bones of the root-relative, heading-free pose (root at the
origin) projected onto the frontal plane, rasterised over every frame of a window into square
cells; the Dice coefficient 2|A n B| / (|A| + |B|) of the cell sets of a system and of the ground
truth says how much of the real gesture space the system covers, and nothing beyond it.
A bone covers the cells of points sampled along it at most half a cell apart.
"""
from __future__ import annotations

import numpy as np

from .params import CoverageParams


def l1_diversity(relative_positions: np.ndarray) -> float:
    """Mean over frames of sum |x_t - mean_t x| over every coordinate of (F, J, 3)."""
    x = np.asarray(relative_positions, np.float64).reshape(len(relative_positions), -1)
    if len(x) == 0:
        return float("nan")
    return float(np.abs(x - x.mean(axis=0)).sum(axis=1).mean())


def bone_samples(length: np.ndarray, cell: float) -> int:
    """Points sampled on the longest bone so that consecutive points are at most half a cell apart."""
    longest = float(np.max(length)) if np.size(length) else 0.0
    return int(np.ceil(longest / (0.5 * cell))) + 1


def covered_cells(relative_positions: np.ndarray, parents, params: CoverageParams) -> np.ndarray:
    """(K, 2) unique integer cells (floor(coordinate / cell)) covered by the projected bones of
    every frame of (F, J, 3); ``parents``: the joints' parent indices (-1 for the root, whose
    entry draws no bone)."""
    p = np.asarray(relative_positions, np.float64)[..., list(params.axes)]
    child = np.array([j for j, q in enumerate(parents) if q >= 0], np.int64)
    if child.size == 0 or len(p) == 0:
        return np.zeros((0, 2), np.int64)
    par = np.asarray(parents, np.int64)[child]
    a, b = p[:, par], p[:, child]                              # (F, B, 2)
    n = bone_samples(np.linalg.norm(b - a, axis=-1), params.cell)
    t = np.linspace(0.0, 1.0, n)[:, None, None, None]
    pts = a[None] + t * (b - a)[None]                           # (n, F, B, 2)
    cells = np.floor(pts.reshape(-1, 2) / params.cell).astype(np.int64)
    lo = cells.min(axis=0)
    span = cells.max(axis=0) - lo + 1
    grid = np.zeros(int(span[0] * span[1]), bool)     # a bitmap over the covered box: O(points), no sort
    grid[(cells[:, 0] - lo[0]) * span[1] + (cells[:, 1] - lo[1])] = True
    k = np.flatnonzero(grid)
    return np.stack([k // span[1] + lo[0], k % span[1] + lo[1]], axis=1)


def dice(cells_a: np.ndarray, cells_b: np.ndarray) -> float:
    """2 |A n B| / (|A| + |B|) of two (K, 2) cell sets; NaN when both are empty."""
    na, nb = len(cells_a), len(cells_b)
    if na + nb == 0:
        return float("nan")
    if na == 0 or nb == 0:
        return 0.0
    both = np.concatenate([np.asarray(cells_a), np.asarray(cells_b)])
    inter = na + nb - len(np.unique(both, axis=0))   # cells are unique within each set
    return 2.0 * inter / (na + nb)


def gesture_area_coverage(relative: np.ndarray, gt_relative: np.ndarray, parents, params: CoverageParams) -> float:
    """GAC of one window: Dice of the covered cells of the system's and the ground truth's poses."""
    return dice(covered_cells(relative, parents, params), covered_cells(gt_relative, parents, params))
