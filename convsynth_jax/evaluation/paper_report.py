"""Tables that put this run's results beside the paper's numbers (``convsynth_jax.paper_values``),
with Wilson 95% confidence intervals on every rate. Pure DataFrame -> DataFrame functions used by
the main job's report (``convsynth_jax.tasks.main``).

Every function selects the columns it needs by name and passes any others through, so extra
columns added to the inputs (e.g. further quality metrics) do not break it. Rows are sorted by
condition (the paper's order: all, no_lr, no_hp, none) and then character.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from .. import paper_values as P
from .summaries import CONDITION_ORDER, HYPOTHESES

# columns of the quality table, in this order when present; other numeric metric columns
# (``seam*``, ``*_ratio``) are appended
QUALITY_COLUMNS = ("num_synthetic_transitions", "diag_mean_transition_cost", "jerk", "gt_jerk", "acceleration",
                   "gt_acceleration", "max_jump", "gt_max_jump", "speed_hellinger", "diversity")
NOT_METRICS = {"fold", "window", "window_start", "window_end", "seed", "fit_seconds", "synthesis_seconds",
               "constraints_total", "constraints_met", "all_constraints_total", "all_constraints_met"}


def wilson(k, n, confidence: float = 0.95) -> tuple[np.ndarray, np.ndarray]:
    """Wilson score intervals of k successes in n trials, elementwise over arrays
    (:func:`convsynth_jax.stats.hypothesis.wilson_interval`; NaN where n is 0)."""
    from ..stats.hypothesis import wilson_interval

    k, n = np.atleast_1d(np.asarray(k, np.float64)), np.atleast_1d(np.asarray(n, np.float64))
    ci = [wilson_interval(a, b, confidence) for a, b in zip(k, n)]
    return np.array([c[0] for c in ci]), np.array([c[1] for c in ci])


def _sort(df: pd.DataFrame) -> pd.DataFrame:
    cond = {c: i for i, c in enumerate(CONDITION_ORDER)}
    hyp = {h: i for i, h in enumerate(HYPOTHESES)}
    keys = [k for k in ("system", "condition", "character", "hypothesis", "k") if k in df]

    def key(s):
        if s.name == "condition":
            return s.map(lambda c: cond.get(c, len(cond)))
        if s.name == "hypothesis":
            return s.map(lambda h: hyp.get(h, len(hyp)))
        return s
    return df.sort_values(keys, key=key, kind="stable").reset_index(drop=True) if keys else df


def table1_beside_paper(table1: pd.DataFrame) -> pd.DataFrame:
    """Table 1 (character, hypothesis, matched, total, rate, ...) with the rate's Wilson interval
    (ci_low, ci_high; kept when the table has them) and the paper's matched / total / rate (and
    interval) for the same character and hypothesis."""
    t = table1.copy()
    if not {"ci_low", "ci_high"} <= set(t.columns):
        t["ci_low"], t["ci_high"] = wilson(t["matched"], t["total"])
    pm = [P.TABLE1.get((c, h), (np.nan, np.nan)) for c, h in zip(t["character"], t["hypothesis"])]
    t["paper_matched"] = [m for m, _ in pm]
    t["paper_total"] = [n for _, n in pm]
    t["paper_rate"] = t["paper_matched"] / t["paper_total"]
    t["paper_ci_low"], t["paper_ci_high"] = wilson(t["paper_matched"].fillna(0), t["paper_total"].fillna(0))
    front = ["character", "hypothesis", "matched", "total", "rate", "ci_low", "ci_high", "paper_matched",
             "paper_total", "paper_rate", "paper_ci_low", "paper_ci_high"]
    return _sort(t[front + [c for c in t.columns if c not in front]])


def table2_beside_paper(rows: pd.DataFrame) -> pd.DataFrame:
    """Graph sizes per character and k (states/edges before and after the SCC) with the paper's
    counts for the same k (the paper has one actor's graph; it is shown beside each character)."""
    t = rows.copy()
    for col in ("states_before_scc", "edges_before_scc", "states_after_scc", "edges_after_scc"):
        t[f"paper_{col}"] = [P.TABLE2.get(int(k), {}).get(col, np.nan) for k in t["k"]]
    t["kept_state_fraction"] = t["states_after_scc"] / t["states_before_scc"]
    t["paper_kept_state_fraction"] = t["paper_states_after_scc"] / t["paper_states_before_scc"]
    return _sort(t)


def table3_beside_paper(timing: pd.DataFrame) -> pd.DataFrame:
    """Table 3 (procedure, mean_s, std_s, n) with the paper's mean and standard deviation."""
    t = timing.copy()
    paper = [P.TABLE3["graph construction"] if str(p).startswith("fit") else
             P.TABLE3["search"] if str(p).startswith("synthesis") else (np.nan, np.nan) for p in t["procedure"]]
    t["paper_mean_s"] = [m for m, _ in paper]
    t["paper_std_s"] = [s for _, s in paper]
    return t


def success_beside_paper(rates: pd.DataFrame) -> pd.DataFrame:
    """Success rate per condition (windows, solved_windows, success_rate, per-character rates...) with
    its Wilson interval and the paper's solved windows / windows / rate where the paper reports one
    (the paper's "test cases" are windows)."""
    t = rates.copy()
    t["ci_low"], t["ci_high"] = wilson(t["solved_windows"], t["windows"])
    pk = [P.SUCCESS.get(c, (np.nan, np.nan)) for c in t["condition"]]
    t["paper_solved_windows"] = [k for k, _ in pk]
    t["paper_windows"] = [n for _, n in pk]
    t["paper_success_rate"] = t["paper_solved_windows"] / t["paper_windows"]
    t["paper_ci_low"], t["paper_ci_high"] = wilson(t["paper_solved_windows"].fillna(0), t["paper_windows"].fillna(0))
    return _sort(t)


def ablation_with_significance(co: pd.DataFrame, alpha: float) -> pd.DataFrame:
    """Co-occurrence per condition x character x hypothesis in synthesized motion vs the held-out
    ground truth (``summaries.cooccurrence_by_condition``) with Wilson intervals on both rates
    (synthesized: ci_low, ci_high; ground truth: gt_ci_low, gt_ci_high; kept when present) and
    ``significant`` (p < alpha)."""
    if co is None or co.empty:
        return pd.DataFrame()
    t = co.copy()
    if not {"ci_low", "ci_high"} <= set(t.columns):
        t["ci_low"], t["ci_high"] = wilson(t["synth_matched"], t["synth_total"])
    if not {"gt_ci_low", "gt_ci_high"} <= set(t.columns):
        t["gt_ci_low"], t["gt_ci_high"] = wilson(t["gt_matched"], t["gt_total"])
    t["significant"] = t["p_value"] < alpha
    return _sort(t)


def user_study_retest(alpha: float = P.USER_STUDY_ALPHA) -> pd.DataFrame:
    """The paper's Figure 6 counts re-tested: R's two-sample ``prop.test`` as the paper ran it
    (a/n vs (n-a)/n), and, because both shares come from the same n answers (they are one
    proportion and its complement, not two samples), the exact one-sample binomial test of
    a/n = 0.5 (``scipy.stats.binomtest``). The paper's reported chi2 and p are beside."""
    from scipy.stats import binomtest

    from ..stats.hypothesis import proportion_test

    rows = []
    for comp, v in P.USER_STUDY.items():
        a, n = v["preferred_a"], v["total"]
        t = proportion_test(a, n - a, n)
        b = binomtest(a, n, 0.5, alternative="two-sided")
        ci = b.proportion_ci(confidence_level=0.95, method="exact")
        rows.append({"comparison": comp, "preferred_a": a, "total": n, "share_a": a / n,
                     "share_ci_low": ci.low, "share_ci_high": ci.high,
                     "prop_test_chi2": t.chi2, "prop_test_p": t.p_value,
                     "paper_chi2": v["chi2"], "paper_p": v["p_value"],
                     "binom_exact_p": b.pvalue, "significant_prop_test": t.p_value < alpha,
                     "significant_binom": b.pvalue < alpha})
    return pd.DataFrame(rows)


def quality_by_condition_character(cases: pd.DataFrame) -> pd.DataFrame:
    """Means of the motion-quality metrics over solved windows, per condition and character, with
    the number of windows. Known metrics first, then any other seam/ratio metric columns."""
    if cases.empty or "success" not in cases:
        return pd.DataFrame()
    ok = cases[cases["success"].fillna(False).astype(bool)]
    if ok.empty:
        return pd.DataFrame()
    cols = [c for c in QUALITY_COLUMNS if c in ok]
    extra = [c for c in ok.columns if c not in cols and c not in NOT_METRICS and pd.api.types.is_numeric_dtype(ok[c])
             and ("seam" in c or c.endswith("_ratio"))]
    keys = [k for k in ("system", "condition", "character") if k in ok]
    out = ok.groupby(keys)[cols + extra].mean()
    out.insert(0, "windows", ok.groupby(keys).size())
    return _sort(out.reset_index())
