"""Our results beside the paper's, with 95% (Wilson) intervals as error bars: Table 1 rates, success
rates per condition, and the co-occurrence ablation. Pure data -> matplotlib Figure (object-oriented
API); the tables come from ``convsynth_jax.evaluation.paper_report``."""
from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from ..panels import panel_row
from .bars import condition_bars

OURS, PAPER = "#4f6fa8", "#d9a441"


def _err(rate, lo, hi):
    r, lo, hi = (np.asarray(a, np.float64) for a in (rate, lo, hi))
    return 100 * np.nan_to_num(np.stack([r - lo, hi - r])).clip(min=0)


def _pair_bars(ax, labels, ours, paper):
    """ours/paper: (rate, ci_low, ci_high) arrays; paper entries may be NaN (not reported)."""
    x = np.arange(len(labels))
    ax.bar(x - 0.2, 100 * np.asarray(ours[0], float), 0.4, yerr=_err(*ours), capsize=3, color=OURS, label="this run")
    p = np.asarray(paper[0], float)
    has = np.isfinite(p)
    if has.any():
        ax.bar(x[has] + 0.2, 100 * p[has], 0.4, yerr=_err(*(np.asarray(a, float)[has] for a in paper)), capsize=3,
               color=PAPER, label="paper")
    for xi in x[~has]:
        ax.text(xi + 0.2, 2, "n/r", ha="center", fontsize=7, color="grey")
    ax.set_xticks(x, labels, rotation=20)
    ax.set_ylim(0, 105)


def table1_beside_paper_figure(t: pd.DataFrame) -> Figure:
    """One panel per character: matched rate per hypothesis, this run vs the paper (Table 1)."""
    chars = list(dict.fromkeys(t["character"]))
    fig, axes = panel_row(len(chars), 4.8, 3.3)
    for ax, c in zip(axes, chars):
        g = t[t["character"] == c]
        _pair_bars(ax, list(g["hypothesis"]), (g["rate"], g["ci_low"], g["ci_high"]),
                   (g["paper_rate"], g["paper_ci_low"], g["paper_ci_high"]))
        ax.set_title(f"Table 1: {c}", fontsize=9)
        ax.set_ylabel("co-occurrence rate (%)")
        ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


def success_beside_paper_figure(t: pd.DataFrame) -> Figure:
    """Windows (test cases) solved per condition, this run vs the paper (n/r: not reported)."""
    fig = Figure(figsize=(6.4, 3.3))
    ax = fig.subplots()
    _pair_bars(ax, list(t["condition"]), (t["success_rate"], t["ci_low"], t["ci_high"]),
               (t["paper_success_rate"], t["paper_ci_low"], t["paper_ci_high"]))
    for i, (k, n) in enumerate(zip(t["solved_windows"], t["windows"])):
        ax.text(i - 0.2, 1, f"{int(k)}/{int(n)}", ha="center", fontsize=7, color="w")
    ax.set_ylabel("windows solved (%)")
    ax.set_title("Success rate per condition (95% CI)", fontsize=9)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    fig.tight_layout()
    return fig


def ablation_ci_figure(co: pd.DataFrame) -> Figure:
    """One panel per character: co-occurrence rate per hypothesis in the held-out ground truth and
    in each condition's synthesized motion, with 95% intervals; * marks p < alpha vs ground truth."""
    chars = list(dict.fromkeys(co["character"]))
    fig, axes = panel_row(len(chars), 5.8, 3.5)
    for ax, char in zip(axes, chars):
        b = condition_bars(co[co["character"] == char])
        gt = b.truth
        ax.bar(b.truth_x, 100 * gt["gt_rate"], b.width, yerr=_err(gt["gt_rate"], gt["gt_ci_low"], gt["gt_ci_high"]),
               capsize=2, color="k", alpha=0.7, label="ground truth")
        for c, r, xi in b.conditions:
            ax.bar(xi, 100 * r["synth_rate"], b.width, yerr=_err(r["synth_rate"], r["ci_low"], r["ci_high"]),
                   capsize=2, label=c)
            for xx, rr, sig in zip(xi, r["ci_high"], r["significant"]):
                if sig is True or sig == 1:
                    ax.text(xx, 100 * rr + 1, "*", ha="center", fontsize=9)
        ax.set_xticks(b.x, b.hypotheses, rotation=20)
        ax.set_ylim(0, 115)
        ax.set_ylabel("co-occurrence rate (%)")
        ax.set_title(char, fontsize=9)
        ax.legend(fontsize=6, ncol=3)
    fig.tight_layout()
    return fig
