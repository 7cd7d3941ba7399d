"""Pure data -> matplotlib Figure helpers for the experiment tables (success rates, ablations)."""
from __future__ import annotations

from matplotlib.figure import Figure
import numpy as np
import pandas as pd

from ..panels import label_panel, panel_row
from .bars import condition_bars
from .table1 import rate_errors


def success_rate_figure(table: pd.DataFrame):
    """Bar chart of the share of windows (test cases) solved per condition."""
    fig = Figure(figsize=(5, 3.2))
    ax = fig.subplots()
    x = np.arange(len(table))
    ax.bar(x, 100 * table["success_rate"], color="#5b7fb5")
    for i, (r, n, k) in enumerate(zip(table["success_rate"], table["windows"], table["solved_windows"])):
        ax.text(i, 100 * r + 1, f"{100 * r:.1f}%\n({k}/{n})", ha="center", va="bottom", fontsize=8)
    ax.set_xticks(x, table["condition"])
    ax.set_ylim(0, 115)
    ax.set_ylabel("windows solved (%)")
    ax.set_title("Search success rate per condition")
    fig.tight_layout()
    return fig


def ablation_figure(co: pd.DataFrame):
    """Grouped bars: co-occurrence rate per hypothesis, ground truth vs each condition (per character),
    with Wilson intervals as error bars when ``co`` has them (gt_ci_low/gt_ci_high, ci_low/ci_high)."""
    chars = sorted(co["character"].unique()) if not co.empty else []
    fig, axes = panel_row(len(chars), 5.5, 3.4)
    for ax, char in zip(axes, chars):
        g = co[co["character"] == char]
        b = condition_bars(g)
        gerr = (rate_errors(b.truth["gt_rate"], b.truth["gt_ci_low"], b.truth["gt_ci_high"])
                if {"gt_ci_low", "gt_ci_high"} <= set(g) else None)
        ax.bar(b.truth_x, 100 * b.truth["gt_rate"].values, b.width, yerr=gerr, capsize=2,
               label="ground truth", color="k", alpha=0.7)
        for c, r, xc in b.conditions:
            err = rate_errors(r["synth_rate"], r["ci_low"], r["ci_high"]) if {"ci_low", "ci_high"} <= set(r) else None
            ax.bar(xc, 100 * r["synth_rate"].values, b.width, yerr=err, capsize=2, label=c)
        ax.set_xticks(b.x, b.hypotheses, rotation=20)
        label_panel(ax, char, "co-occurrence rate (%)")
    fig.tight_layout()
    return fig
