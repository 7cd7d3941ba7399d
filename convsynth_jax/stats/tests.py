"""Hypothesis tests: two-sample proportion test (R's prop.test), 2x2 chi-square, permutation test."""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy import stats


class ProportionTest(NamedTuple):
    chi2: float
    df: int
    p_value: float
    estimates: tuple


def prop_test(x: tuple, n: tuple, correct: bool = True) -> ProportionTest:
    """R's ``prop.test(x, n, correct=TRUE)`` for two groups: Pearson chi-square on the 2x2 table with
    R's continuity correction min(0.5, |x1 - E11|) applied to every |observed - expected|."""
    x = np.asarray(x, dtype=np.float64)
    n = np.asarray(n, dtype=np.float64)
    if x.shape != (2,) or n.shape != (2,):
        raise ValueError("prop_test takes two counts and two totals")
    if np.any(n <= 0) or np.any(x < 0) or np.any(x > n):
        raise ValueError(f"need 0 <= x <= n and n > 0, got x={x.tolist()}, n={n.tolist()}")
    table = np.stack([x, n - x], axis=1)  # rows: groups; cols: success, failure
    expected = table.sum(1, keepdims=True) * table.sum(0, keepdims=True) / table.sum()
    if np.any(expected == 0):
        return ProportionTest(0.0, 1, 1.0, tuple(x / n))
    yates = min(0.5, float(np.abs(table - expected).min())) if correct else 0.0
    chi2 = float(np.sum((np.abs(table - expected) - yates) ** 2 / expected))
    return ProportionTest(chi2, 1, float(stats.chi2.sf(chi2, 1)), tuple(x / n))


def proportion_test(count_a: int, count_b: int, n: int) -> ProportionTest:
    """The paper's forced-choice comparison (Figure 6): of ``n`` answers, ``count_a`` preferred method
    A and ``count_b`` preferred B; tests count_a/n against count_b/n (R: prop.test(c(a, b), c(n, n)))."""
    return prop_test((count_a, count_b), (n, n))


class ContingencyResult(NamedTuple):
    chi2: float
    df: int
    p_value: float


def chi2_independence(matched_a: int, total_a: int, matched_b: int, total_b: int) -> ContingencyResult:
    """Chi-square test of independence on [[matched_a, unmatched_a], [matched_b, unmatched_b]]
    (scipy, Yates-corrected as is usual for 2x2)."""
    table = np.array([[matched_a, total_a - matched_a], [matched_b, total_b - matched_b]], dtype=np.float64)
    if np.any(table.sum(0) == 0) or np.any(table.sum(1) == 0):
        return ContingencyResult(0.0, 1, 1.0)
    chi2, p, dof, _ = stats.chi2_contingency(table, correction=True)
    return ContingencyResult(float(chi2), int(dof), float(p))


def permutation_test(a: np.ndarray, b: np.ndarray, n_permutations: int = 5000, seed: int = 0) -> float:
    """One-sided p-value that mean(a) > mean(b) under random relabelling (vectorized); includes the
    observed labelling, so p >= 1 / (n_permutations + 1)."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    if a.size == 0 or b.size == 0:
        return 1.0
    pooled = np.concatenate([a, b])
    observed = a.mean() - b.mean()
    rng = np.random.default_rng(seed)
    keys = rng.random((n_permutations, pooled.size))
    perm = np.argsort(keys, axis=1)
    sa = pooled[perm[:, : a.size]].mean(axis=1)
    sb = pooled[perm[:, a.size:]].mean(axis=1)
    return float((np.sum(sa - sb >= observed - 1e-12) + 1) / (n_permutations + 1))
