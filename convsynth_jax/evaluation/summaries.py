"""Summary tables over collected leave-one-out test cases (one row per window x character x condition).

Pure functions DataFrame -> DataFrame used by the collect task, the figure scripts and notebooks.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

HYPOTHESES = ("PC-LH", "PC-RH", "PC-LH/RH", "LR-Nod", "PH-Nod")
CONDITION_ORDER = ("all", "no_lr", "no_hp", "none")


def _ordered(df: pd.DataFrame, col: str = "condition") -> pd.DataFrame:
    order = {c: i for i, c in enumerate(CONDITION_ORDER)}
    return df.sort_values(col, key=lambda s: s.map(lambda c: order.get(c, len(order)))).reset_index(drop=True)


def test_cases(cases: pd.DataFrame) -> pd.DataFrame:
    """One row per test case (fold x window x condition): a case succeeds when every character
    succeeded (the paper counts a window as solved when motion was found for it)."""
    ok = cases.assign(success=cases["success"].fillna(False).astype(bool))
    keys = [k for k in ("fold", "session", "condition", "window") if k in ok]
    return ok.groupby(keys, dropna=False)["success"].all().reset_index()


def success_rates(cases: pd.DataFrame) -> pd.DataFrame:
    """Per condition: number of test cases, solved cases, success rate, and per-character rates."""
    tc = test_cases(cases)
    out = tc.groupby("condition")["success"].agg(cases="count", solved="sum").reset_index()
    out["success_rate"] = out["solved"] / out["cases"]
    per_char = cases.assign(success=cases["success"].fillna(False).astype(bool)).pivot_table(
        index="condition", columns="character", values="success", aggfunc="mean")
    per_char.columns = [f"success_rate_{c}" for c in per_char.columns]
    out = out.merge(per_char.reset_index(), on="condition", how="left")
    return _ordered(out)


def timing_table(cases: pd.DataFrame) -> pd.DataFrame:
    """Table 3: mean and standard deviation of graph construction and search wall-clock time.
    Construction is counted once per fold and character; search once per window and character."""
    rows = []
    if "construction_seconds" in cases:
        cons = cases.drop_duplicates(["fold", "character"])["construction_seconds"].dropna()
        rows.append({"procedure": "graph construction", "mean_s": cons.mean(), "std_s": cons.std(ddof=1),
                     "n": int(cons.count())})
    srch = cases["search_seconds"].dropna()
    rows.append({"procedure": "search", "mean_s": srch.mean(), "std_s": srch.std(ddof=1), "n": int(srch.count())})
    return pd.DataFrame(rows)


def cooccurrence_by_condition(cases: pd.DataFrame) -> pd.DataFrame:
    """Co-occurrence rates on synthesized motion per condition and character next to the held-out
    ground truth, with a two-sample proportion test (continuity-corrected chi-square)."""
    rows = []
    for (cond, char), g in cases.groupby(["condition", "character"]):
        for h in HYPOTHESES:
            cols = [f"synth_{h}_matched", f"synth_{h}_total", f"gt_{h}_matched", f"gt_{h}_total"]
            if not all(c in g for c in cols):
                continue
            sg = g[g["success"].fillna(False).astype(bool)]
            sm, st = int(sg[cols[0]].sum()), int(sg[cols[1]].sum())
            gm, gt = int(g[cols[2]].sum()), int(g[cols[3]].sum())
            res = _two_sample_test(sm, st, gm, gt) if st > 0 and gt > 0 else None
            rows.append({
                "condition": cond, "character": char, "hypothesis": h,
                "synth_matched": sm, "synth_total": st, "synth_rate": sm / st if st else np.nan,
                "gt_matched": gm, "gt_total": gt, "gt_rate": gm / gt if gt else np.nan,
                "chi2": res.chi2 if res else np.nan, "p_value": res.p_value if res else np.nan,
            })
    return _ordered(pd.DataFrame(rows)) if rows else pd.DataFrame()


def _two_sample_test(x1: int, n1: int, x2: int, n2: int):
    """Continuity-corrected chi-square test of equal proportions x1/n1 vs x2/n2 (2x2 table)."""
    from types import SimpleNamespace

    from scipy.stats import chi2_contingency

    table = np.array([[x1, n1 - x1], [x2, n2 - x2]], dtype=float)
    if (table.sum(axis=0) == 0).any():
        return SimpleNamespace(chi2=0.0, p_value=1.0)
    chi2, p, _, _ = chi2_contingency(table, correction=True)
    return SimpleNamespace(chi2=float(chi2), p_value=float(p))


def quality_by_condition(cases: pd.DataFrame) -> pd.DataFrame:
    """Motion-quality metrics of successful cases per condition (means)."""
    metric_cols = [c for c in ("jerk", "gt_jerk", "acceleration", "gt_acceleration", "speed_hellinger",
                               "mean_transition_cost", "num_synthetic_transitions", "max_jump", "gt_max_jump",
                               "cost", "diversity") if c in cases]
    ok = cases[cases["success"].fillna(False).astype(bool)]
    if ok.empty:
        return pd.DataFrame({"condition": []})
    out = ok.groupby("condition")[metric_cols].mean().reset_index()
    return _ordered(out)


def to_markdown(df: pd.DataFrame, floatfmt: str = ".4g") -> str:
    """A GitHub Markdown table (no tabulate dependency)."""
    if df is None or df.empty:
        return "_(no rows)_\n"
    cols = list(df.columns)

    def fmt(v):
        if isinstance(v, (float, np.floating)):
            return "" if np.isnan(v) else format(float(v), floatfmt)
        return str(v)

    lines = ["| " + " | ".join(cols) + " |", "|" + "|".join("---" for _ in cols) + "|"]
    for row in df.itertuples(index=False):
        lines.append("| " + " | ".join(fmt(v) for v in row) + " |")
    return "\n".join(lines) + "\n"


def to_latex(df: pd.DataFrame, floatfmt: str = ".4g") -> str:
    """A booktabs LaTeX tabular (no jinja2 dependency)."""
    def esc(v):
        if isinstance(v, (float, np.floating)):
            return "" if np.isnan(v) else format(float(v), floatfmt)
        s = str(v)
        for a, b in (("\\", r"\textbackslash{}"), ("&", r"\&"), ("%", r"\%"), ("_", r"\_"), ("#", r"\#")):
            s = s.replace(a, b)
        return s

    cols = list(df.columns)
    lines = [r"\begin{tabular}{" + "l" * len(cols) + "}", r"\toprule", " & ".join(esc(c) for c in cols) + r" \\",
             r"\midrule"]
    lines += [" & ".join(esc(v) for v in row) + r" \\" for row in df.itertuples(index=False)]
    lines += [r"\bottomrule", r"\end{tabular}"]
    return "\n".join(lines) + "\n"
