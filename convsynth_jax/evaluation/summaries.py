"""Summary tables over collected leave-one-out test cases (one row per window x character x condition).

Pure functions DataFrame -> DataFrame used by the collect task, the figure scripts and notebooks.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from ..annotate.kinds import HYPOTHESES  # noqa: F401  (the registry's table, re-exported for the reports)
CONDITION_ORDER = ("all", "no_lr", "no_hp", "none")


def _ordered(df: pd.DataFrame, col: str = "condition") -> pd.DataFrame:
    """Rows sorted by system, then condition (the paper's order first), then character."""
    order = {c: i for i, c in enumerate(CONDITION_ORDER)}
    keys = [k for k in ("system", col, "character") if k in df]
    return df.sort_values(keys, key=lambda s: s.map(lambda c: order.get(c, len(order))) if s.name == col else s,
                          kind="stable").reset_index(drop=True)


def _group_keys(cases: pd.DataFrame, *rest: str) -> list[str]:
    return (["system"] if "system" in cases else []) + list(rest)


def test_cases(cases: pd.DataFrame) -> pd.DataFrame:
    """One row per window (test case: fold x window x condition): a window is solved when every
    character in it succeeded (the paper counts a window as solved when motion was found for it)."""
    ok = cases.assign(success=cases["success"].fillna(False).astype(bool))
    keys = [k for k in ("system", "fold", "session", "condition", "window") if k in ok]
    return ok.groupby(keys, dropna=False)["success"].all().reset_index()


def success_rates(cases: pd.DataFrame) -> pd.DataFrame:
    """Per condition: ``windows`` (test cases), ``solved_windows`` (every character solved),
    ``success_rate`` (their share), and per character the share of its character-windows solved
    (``success_rate_<character>``). ``cases`` has one row per character-window."""
    tc = test_cases(cases)
    keys = _group_keys(cases, "condition")
    out = tc.groupby(keys)["success"].agg(windows="count", solved_windows="sum").reset_index()
    out["success_rate"] = out["solved_windows"] / out["windows"]
    per_char = cases.assign(success=cases["success"].fillna(False).astype(bool)).pivot_table(
        index=keys, columns="character", values="success", aggfunc="mean")
    per_char.columns = [f"success_rate_{c}" for c in per_char.columns]
    out = out.merge(per_char.reset_index(), on=keys, how="left")
    return _ordered(out)


def success_by_character(cases: pd.DataFrame) -> pd.DataFrame:
    """Per condition and character: ``character_windows``, ``solved_character_windows`` and their share."""
    ok = cases.assign(success=cases["success"].fillna(False).astype(bool))
    keys = _group_keys(cases, "condition", "character")
    out = ok.groupby(keys)["success"].agg(character_windows="count", solved_character_windows="sum").reset_index()
    out["success_rate"] = out["solved_character_windows"] / out["character_windows"]
    return _ordered(out)


def _condition_sorted(df: pd.DataFrame, keys: list) -> pd.DataFrame:
    order = {c: i for i, c in enumerate(CONDITION_ORDER)}
    by = [k for k in keys if k in df] + ["speaker", "condition"]
    return df.sort_values(by, key=lambda s: s.map(lambda c: order.get(c, len(order))) if s.name == "condition" else s,
                          kind="stable").reset_index(drop=True)


def _reference_constraints(cons: pd.DataFrame, group: dict, reference: str) -> tuple[set, str]:
    """The constraints (kind, start, end) of the reference condition's job for one speaker (and sweep
    point ``group``); without that condition in the sweep, the union over its conditions."""
    g = cons
    for k, v in group.items():
        g = g[g[k].astype(str) == str(v)]
    ref = g[g["condition"] == reference]
    name = reference
    if ref.empty:
        ref, name = g, "union"
    return set(zip(ref["kind"], ref["start"], ref["end"])), name


def _own_constraints(cons: pd.DataFrame, job_dir, speaker) -> dict:
    own = cons[(cons["job_dir"] == job_dir) & (cons["speaker"] == speaker)]
    return {(k, s, e): bool(m) for k, s, e, m in zip(own["kind"], own["start"], own["end"], own["met"])}


def _per_speaker(constraints: pd.DataFrame, speakers: pd.DataFrame, keys, reference: str):
    """Per speaker row of a converse sweep: (the row, the reference condition's constraints (kind, start,
    end), the reference's name, the row's own checked constraints -> met, the kinds its condition switches off)."""
    for sp in speakers.to_dict("records"):
        group = {**{k: sp[k] for k in keys}, "speaker": sp["speaker"]}
        ref, ref_name = _reference_constraints(constraints, group, reference) if len(constraints) else (set(), reference)
        own = _own_constraints(constraints, sp["job_dir"], sp["speaker"]) if len(constraints) else {}
        yield sp, ref, ref_name, own, {k for k in str(sp.get("kinds_off") or "").split(",") if k}


def converse_constraints_met(constraints: pd.DataFrame, speakers: pd.DataFrame, keys=(),
                             reference: str = "all") -> pd.DataFrame:
    """Constraints met per condition and speaker of a converse sweep, on the same denominator in every
    condition: the constraints the checker judged under ``reference`` (condition all: every kind on)
    for that speaker, matched by kind, start and end. ``constraints``: the reference's count;
    ``switched_off``: how many of them are of kinds the condition switches off (``kinds_off``: neither
    searched for nor checked under it; reported apart, never counted as met); ``on``: the others;
    ``met``; ``share_met`` = met / constraints (comparable across conditions); ``share_met_on`` =
    met / on; ``not_checked``: of kinds on but absent from the condition's check; ``checked`` / ``checked_met``: the
    condition's own count, as its report gives it. ``keys``: the sweep's other axes."""
    keys = [k for k in keys if k in speakers]
    rows = []
    if speakers.empty:
        return pd.DataFrame()
    for sp, ref, ref_name, own, off in _per_speaker(constraints, speakers, keys, reference):
        on = [c for c in ref if c[0] not in off]
        met = sum(own.get(c, False) for c in on)
        n = len(ref)
        rows.append({**{k: sp[k] for k in keys}, "condition": sp["condition"], "speaker": sp["speaker"],
                     "character": sp.get("character"), "success": sp.get("success"), "reference": ref_name,
                     "constraints": n, "met": met, "share_met": met / n if n else np.nan,
                     "switched_off": n - len(on), "kinds_off": ",".join(sorted(off)), "on": len(on),
                     "share_met_on": met / len(on) if on else np.nan,
                     "not_checked": sum(c not in own for c in on),
                     "checked": len(own), "checked_met": sum(own.values())})
    return _condition_sorted(pd.DataFrame(rows), keys)


def converse_constraints_by_kind(constraints: pd.DataFrame, speakers: pd.DataFrame, keys=(),
                                 reference: str = "all") -> pd.DataFrame:
    """:func:`converse_constraints_met` split by constraint kind (the registry's order): per condition,
    speaker and kind, the reference's ``constraints``, ``met`` and whether the condition asks for the
    kind (``on``)."""
    from ..annotate.kinds import constraint_kinds

    keys = [k for k in keys if k in speakers]
    rows = []
    if speakers.empty:
        return pd.DataFrame()
    for sp, ref, _, own, off in _per_speaker(constraints, speakers, keys, reference):
        for kind in [k.name for k in constraint_kinds()]:
            mine = [c for c in ref if c[0] == kind]
            rows.append({**{k: sp[k] for k in keys}, "condition": sp["condition"], "speaker": sp["speaker"],
                         "character": sp.get("character"), "kind": kind, "on": kind not in off,
                         "constraints": len(mine), "met": sum(own.get(c, False) for c in mine) if kind not in off else 0,
                         "share_met": (sum(own.get(c, False) for c in mine) / len(mine)) if mine and kind not in off else np.nan})
    return _condition_sorted(pd.DataFrame(rows), keys)


def leaderboard_wide(board: pd.DataFrame, keys=()) -> pd.DataFrame:
    """A benchmark leaderboard with one row per (sweep point,) scope and system and one column per metric."""
    index = [k for k in keys if k in board] + ["scope", "system"]
    wide = board.pivot_table(index=index, columns="metric", values="value", aggfunc="first", sort=False)
    wide.columns = [str(c) for c in wide.columns]
    return wide.reset_index()


def timing_table(cases: pd.DataFrame) -> pd.DataFrame:
    """Table 3: mean and standard deviation of the fitting and synthesis wall-clock time, per system,
    each named as the system names it (the rows' ``fit_procedure`` / ``synthesis_procedure``, e.g. the
    motion graph's "fit (graph construction)"; "fit" / "synthesis" for rows without them). Fitting is
    counted once per fold and character; synthesis once per window and character."""
    def named(g, column, default):
        names = g[column].dropna() if column in g else ()
        return str(names.iloc[0]) if len(names) else default

    rows = []
    groups = cases.groupby("system") if "system" in cases else [("", cases)]
    for system, g in groups:
        base = {"system": system} if system != "" else {}
        if "fit_seconds" in g:
            fit = g.drop_duplicates(["fold", "character"])["fit_seconds"].dropna()
            rows.append({**base, "procedure": named(g, "fit_procedure", "fit"),
                         "mean_s": fit.mean(), "std_s": fit.std(ddof=1), "n": int(fit.count())})
        if "synthesis_seconds" in g:
            syn = g["synthesis_seconds"].dropna()
            rows.append({**base, "procedure": named(g, "synthesis_procedure", "synthesis"),
                         "mean_s": syn.mean(), "std_s": syn.std(ddof=1), "n": int(syn.count())})
    return pd.DataFrame(rows)


def cooccurrence_by_condition(cases: pd.DataFrame, confidence: float = 0.95) -> pd.DataFrame:
    """Co-occurrence rates on synthesized motion per condition and character next to the held-out
    ground truth (both counted by Table 1's measure with recording thresholds, see
    ``evaluation.loo``), each with its Wilson interval at ``confidence`` (synth: ci_low, ci_high;
    ground truth: gt_ci_low, gt_ci_high), a two-sample proportion test (continuity-corrected
    chi-square: chi2, p_value) and, paired by window, a Wilcoxon signed-rank test of the per-window
    matched rates of the successful windows with audio segments of the hypothesis (n_pairs,
    p_wilcoxon). Hypotheses a system does not produce (NaN totals) are left out."""
    from ..stats.hypothesis import paired_rate_test, wilson_interval

    rows = []
    keys = _group_keys(cases, "condition", "character")
    for key, g in cases.groupby(keys):
        for h in HYPOTHESES:
            cols = [f"synth_{h}_matched", f"synth_{h}_total", f"gt_{h}_matched", f"gt_{h}_total"]
            if not all(c in g for c in cols):
                continue
            sg = g[g["success"].fillna(False).astype(bool)]
            if len(sg) and sg[cols[1]].isna().all():  # the system makes no such motion: not applicable
                continue
            sm, st = int(sg[cols[0]].sum()), int(sg[cols[1]].sum())
            gm, gt = int(g[cols[2]].sum()), int(g[cols[3]].sum())
            res = _two_sample_test(sm, st, gm, gt) if st > 0 and gt > 0 else None
            paired = sg[(sg[cols[1]] > 0) & (sg[cols[3]] > 0)]
            _, p_w, n_pairs = paired_rate_test(paired[cols[0]] / paired[cols[1]], paired[cols[2]] / paired[cols[3]])
            slo, shi = wilson_interval(sm, st, confidence)
            glo, ghi = wilson_interval(gm, gt, confidence)
            rows.append({
                **dict(zip(keys, key)), "hypothesis": h,
                "synth_matched": sm, "synth_total": st, "synth_rate": sm / st if st else np.nan,
                "ci_low": slo, "ci_high": shi,
                "gt_matched": gm, "gt_total": gt, "gt_rate": gm / gt if gt else np.nan,
                "gt_ci_low": glo, "gt_ci_high": ghi,
                "chi2": res.chi2 if res else np.nan, "p_value": res.p_value if res else np.nan,
                "n_pairs": n_pairs, "p_wilcoxon": p_w,
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
                               "diag_mean_transition_cost", "num_synthetic_transitions", "max_jump", "gt_max_jump",
                               "diag_cost", "diversity", "seam_ratio") if c in cases]
    ok = cases[cases["success"].fillna(False).astype(bool)]
    if ok.empty:
        return pd.DataFrame({"condition": []})
    out = ok.groupby(_group_keys(ok, "condition"))[metric_cols].mean().reset_index()
    if "seam_ratio" in ok:  # the seam goal (<= 1) is per window: show the worst one too
        worst = ok.groupby(_group_keys(ok, "condition"))["seam_ratio"].max().rename("seam_ratio_max")
        out = out.merge(worst.reset_index(), on=_group_keys(ok, "condition"), how="left")
    if "metric_scope" in ok:  # "body" (every joint) or "head" (head-only systems): what the means are over
        scope = ok.groupby(_group_keys(ok, "condition"))["metric_scope"].first().rename("metric_scope")
        out = out.merge(scope.reset_index(), on=_group_keys(ok, "condition"), how="left")
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
