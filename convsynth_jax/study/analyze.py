"""Figure 6 from a study's answers (paper Section 8.2).

Exported answers (``/admin/export.csv``) -> participants failing attention checks excluded (and
counted) -> per-pair counts (answers preferring condition A of all answers) -> per pair the paper's
test, R's two-sample ``prop.test`` with continuity correction of a/n against (n-a)/n, and the exact
one-sample binomial test of a/n = 0.5 (both shares come from the same n answers, so the binomial is
the test that fits; :func:`convsynth_jax.evaluation.paper_report.user_study_retest` reports both for
the paper's counts). :func:`forced_choice_table` is also what ``task=user_study`` runs on a counts
CSV.
"""
from __future__ import annotations

from pathlib import Path

import pandas as pd

from ..errors import FormatError
from ..stats.hypothesis import proportion_test

ANSWER_FIELDS = ("participant", "trial", "stimulus", "kind", "pair", "condition_a", "condition_b", "chosen_side",
                 "chosen_condition", "expected")


def forced_choice_table(df: pd.DataFrame, path=None, alpha: float = 0.03) -> pd.DataFrame:
    """One row per comparison: the input columns (comparison, preferred_a, total, optional method_a,
    method_b) plus preferred_b, share_a, chi2, df, p_value (prop.test), binom_p, share_ci_low/high
    (exact binomial, 95 %) and significant (p_value < alpha; the paper stars p < 0.03). Bad rows
    raise FormatError naming the line."""
    from scipy.stats import binomtest

    need = {"comparison", "preferred_a", "total"}
    if not need <= set(df.columns):
        raise FormatError(f"user-study CSV needs columns {sorted(need)}, has {list(df.columns)}", path, "line 1")
    rows = []
    for i, r in df.reset_index(drop=True).iterrows():
        try:
            a_f, n_f = float(r["preferred_a"]), float(r["total"])
        except (TypeError, ValueError):
            a_f = n_f = float("nan")
        if not (a_f == a_f and n_f == n_f) or a_f != int(a_f) or n_f != int(n_f):
            raise FormatError(f"preferred_a and total must be integers, got {r['preferred_a']!r}, {r['total']!r}",
                              path, f"line {i + 2}")
        a, n = int(a_f), int(n_f)
        if not 0 <= a <= n or n <= 0:
            raise FormatError(f"preferred_a={a} and total={n} are inconsistent (need 0 <= preferred_a <= total)",
                              path, f"line {i + 2}")
        t = proportion_test(a, n - a, n)
        b = binomtest(a, n, 0.5, alternative="two-sided")
        ci = b.proportion_ci(confidence_level=0.95, method="exact")
        rows.append({**r.to_dict(), "preferred_b": n - a, "share_a": a / n, "chi2": t.chi2, "df": t.df,
                     "p_value": t.p_value, "binom_p": b.pvalue, "share_ci_low": ci.low, "share_ci_high": ci.high,
                     "significant": bool(t.p_value < alpha)})
    return pd.DataFrame(rows)


def read_answers(path: str | Path) -> pd.DataFrame:
    """An export CSV of ``/admin/export.csv``; FormatError names the file and the line."""
    from ..errors import MissingFileError

    p = Path(path)
    if not p.is_file():
        raise MissingFileError("answers CSV not found", p)
    try:
        df = pd.read_csv(p, dtype={"participant": str, "stimulus": str, "expected": str})
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as e:
        raise FormatError(f"not a readable CSV ({e})", p) from None
    missing = set(ANSWER_FIELDS) - set(df.columns)
    if missing:
        raise FormatError(f"answers CSV lacks columns {sorted(missing)}", p, "line 1")
    bad = df.index[~df["chosen_side"].isin(["left", "right"])]
    if len(bad):
        raise FormatError(f"chosen_side must be left or right, got {df['chosen_side'].iat[int(bad[0])]!r}", p,
                          f"line {int(bad[0]) + 2}")
    dup = df.duplicated(["participant", "trial"])
    if dup.any():
        i = int(df.index[dup][0])
        raise FormatError(f"participant {df['participant'].iat[i]} answers trial {df['trial'].iat[i]} twice", p, f"line {i + 2}")
    return df


def attention_report(answers: pd.DataFrame, max_failed: int = 0) -> pd.DataFrame:
    """One row per participant: attention checks answered, failed (the frozen side chosen), excluded
    (failed > ``max_failed``)."""
    parts = sorted(answers["participant"].unique())
    att = answers[answers["kind"] == "attention"]
    failed = (att["chosen_side"] != att["expected"]).groupby(att["participant"]).sum()
    checks = att.groupby("participant").size()
    rows = [{"participant": p, "checks": int(checks.get(p, 0)), "failed": int(failed.get(p, 0))} for p in parts]
    out = pd.DataFrame(rows, columns=["participant", "checks", "failed"])
    out["excluded"] = out["failed"] > max_failed
    return out


def pair_counts(answers: pd.DataFrame, pairs) -> pd.DataFrame:
    """Per pair (``design.Pair``, in order): comparison, method_a, method_b, preferred_a, total."""
    rows = []
    for p in pairs:
        a = answers[(answers["kind"] == "pair") & (answers["pair"] == p.name)]
        rows.append({"comparison": f"{p.label_a} vs {p.label_b}", "method_a": p.label_a, "method_b": p.label_b,
                     "pair": p.name, "preferred_a": int((a["chosen_condition"] == p.a).sum()), "total": int(len(a))})
    return pd.DataFrame(rows)


def analyze_answers(answers: pd.DataFrame, pairs, alpha: float = 0.03, max_failed: int = 0):
    """(tests per pair, attention report): participants failing more than ``max_failed`` attention
    checks are left out of the counts. Pairs without answers are left out of the tests."""
    att = attention_report(answers, max_failed)
    kept = answers[~answers["participant"].isin(att.loc[att["excluded"], "participant"])]
    counts = pair_counts(kept, pairs)
    counts = counts[counts["total"] > 0].reset_index(drop=True)
    table = forced_choice_table(counts, alpha=alpha) if len(counts) else counts
    return table, att
