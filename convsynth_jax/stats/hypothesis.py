"""Hypothesis tests: two-sample proportion test (R's prop.test), 2x2 chi-square, permutation test."""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy import stats

from ..errors import ConvSynthError


class CountError(ConvSynthError, ValueError):
    """Counts given to a test are impossible (negative, above their total, not integers)."""


class ProportionTest(NamedTuple):
    """Result of ``prop_test``: Pearson chi-square (continuity-corrected), degrees of freedom,
    p-value (two-sided), and the two sample proportions."""

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
        raise CountError("prop_test takes two counts and two totals", where=f"x={x.tolist()}, n={n.tolist()}")
    if np.any(n <= 0) or np.any(x < 0) or np.any(x > n) or np.any(x != np.round(x)) or np.any(n != np.round(n)):
        raise CountError("need integer counts with 0 <= x <= n and n > 0", where=f"x={x.tolist()}, n={n.tolist()}")
    table = np.stack([x, n - x], axis=1)  # rows: groups; cols: success, failure
    expected = table.sum(1, keepdims=True) * table.sum(0, keepdims=True) / table.sum()
    if np.any(expected == 0):
        return ProportionTest(0.0, 1, 1.0, tuple(x / n))
    yates = min(0.5, float(np.abs(table - expected).min())) if correct else 0.0
    chi2 = float(np.sum((np.abs(table - expected) - yates) ** 2 / expected))
    return ProportionTest(chi2, 1, float(stats.chi2.sf(chi2, 1)), tuple(x / n))


def proportion_test(count_a: int, count_b: int, n: int) -> ProportionTest:
    """The paper's forced-choice comparison (Figure 6): of ``n`` answers, ``count_a`` preferred method
    A and ``count_b`` preferred B; tests count_a/n against count_b/n (R: prop.test(c(a, b), c(n, n))).
    This is how the paper's Figure 6 statistics come out (e.g. 64 vs 142 of 206: chi2 = 57.563)."""
    if count_a + count_b > n:
        raise CountError(f"count_a + count_b = {count_a + count_b} exceeds the {n} answers",
                         where=f"count_a={count_a}, count_b={count_b}, n={n}")
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


def permutation_test(a: np.ndarray, b: np.ndarray, n_permutations: int = 5000, seed: int = 0,
                     block: int = 512) -> float:
    """One-sided p-value that mean(a) > mean(b) under random relabelling of the pooled values.

    a: (Na,), b: (Nb,) values (here 0/1 match flags of audio and random windows). Vectorized over
    permutations in blocks of ``block`` (memory block x (Na + Nb)); the observed labelling is
    counted, so p >= 1 / (n_permutations + 1). Deterministic for a given seed."""
    a = np.asarray(a, dtype=np.float64).ravel()
    b = np.asarray(b, dtype=np.float64).ravel()
    if a.size == 0 or b.size == 0:
        return 1.0
    pooled = np.concatenate([a, b])
    observed = a.mean() - b.mean()
    rng = np.random.default_rng(seed)
    total = pooled.sum()
    exceed = 0
    for lo in range(0, n_permutations, block):
        m = min(block, n_permutations - lo)
        perm = np.argsort(rng.random((m, pooled.size)), axis=1)[:, : a.size]
        sa = pooled[perm].sum(axis=1)
        diff = sa / a.size - (total - sa) / b.size
        exceed += int(np.sum(diff >= observed - 1e-12))
    return float((exceed + 1) / (n_permutations + 1))


def wilson_interval(matched, total, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson score interval of the proportion matched/total at ``confidence`` (statsmodels
    ``proportion_confint(method="wilson")``); (nan, nan) when total is 0 or not a number.

    The bounds at the ends are exact: the Wilson interval's lower bound is 0 when nothing matched
    and its upper bound 1 when everything did (statsmodels returns round-off such as 5.6e-17)."""
    from statsmodels.stats.proportion import proportion_confint

    if total is None or not np.isfinite(total) or total <= 0 or matched is None or not np.isfinite(matched):
        return float("nan"), float("nan")
    if matched < 0 or matched > total:
        raise CountError("need 0 <= matched <= total", where=f"matched={matched}, total={total}")
    lo, hi = proportion_confint(int(matched), int(total), alpha=1.0 - confidence, method="wilson")
    if int(matched) == 0:
        lo = 0.0
    if int(matched) == int(total):
        hi = 1.0
    return float(lo), float(hi)


def paired_rate_test(a, b) -> tuple[float, float, int]:
    """Wilcoxon signed-rank test (scipy, two-sided, zero differences dropped) of paired per-window
    rates a vs b (equal-length arrays; pairs with a NaN are left out): (statistic, p, pairs used).
    With no non-zero difference the rates agree on every pair: (0.0, 1.0, n)."""
    a = np.asarray(a, dtype=np.float64).ravel()
    b = np.asarray(b, dtype=np.float64).ravel()
    if a.shape != b.shape:
        raise CountError("paired test needs arrays of equal length", where=f"{a.size} vs {b.size}")
    keep = np.isfinite(a) & np.isfinite(b)
    a, b = a[keep], b[keep]
    n = int(a.size)
    if n == 0:
        return float("nan"), float("nan"), 0
    if not np.any(a != b):
        return 0.0, 1.0, n
    res = stats.wilcoxon(a, b, zero_method="wilcox", alternative="two-sided")
    return float(res.statistic), float(res.pvalue), n
