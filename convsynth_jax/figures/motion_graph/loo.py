"""Pure data -> matplotlib Figure helpers for the experiment tables (success rates, ablations)."""
from __future__ import annotations

from matplotlib.figure import Figure
import numpy as np
import pandas as pd

from .table1 import rate_errors


def success_rate_figure(table: pd.DataFrame):
    """Bar chart of the test-case success rate per condition."""
    fig = Figure(figsize=(5, 3.2))
    ax = fig.subplots()
    x = np.arange(len(table))
    ax.bar(x, 100 * table["success_rate"], color="#5b7fb5")
    for i, (r, n, k) in enumerate(zip(table["success_rate"], table["cases"], table["solved"])):
        ax.text(i, 100 * r + 1, f"{100 * r:.1f}%\n({k}/{n})", ha="center", va="bottom", fontsize=8)
    ax.set_xticks(x, table["condition"])
    ax.set_ylim(0, 115)
    ax.set_ylabel("test cases solved (%)")
    ax.set_title("Search success rate per condition")
    fig.tight_layout()
    return fig


def ablation_figure(co: pd.DataFrame):
    """Grouped bars: co-occurrence rate per hypothesis, ground truth vs each condition (per character),
    with Wilson intervals as error bars when ``co`` has them (gt_ci_low/gt_ci_high, ci_low/ci_high)."""
    chars = sorted(co["character"].unique()) if not co.empty else []
    fig = Figure(figsize=(5.5 * max(1, len(chars)), 3.4))
    axes = fig.subplots(1, max(1, len(chars)), squeeze=False)
    for ax, char in zip(axes[0], chars):
        g = co[co["character"] == char]
        hyps = list(dict.fromkeys(g["hypothesis"]))
        conds = list(dict.fromkeys(g["condition"]))
        width = 0.8 / (len(conds) + 1)
        x = np.arange(len(hyps))
        first = g.groupby("hypothesis").first().reindex(hyps)
        gerr = (rate_errors(first["gt_rate"], first["gt_ci_low"], first["gt_ci_high"])
                if {"gt_ci_low", "gt_ci_high"} <= set(g) else None)
        ax.bar(x - 0.4 + width / 2, 100 * first["gt_rate"].values, width, yerr=gerr, capsize=2,
               label="ground truth", color="k", alpha=0.7)
        for i, c in enumerate(conds):
            r = g[g["condition"] == c].set_index("hypothesis").reindex(hyps)
            err = rate_errors(r["synth_rate"], r["ci_low"], r["ci_high"]) if {"ci_low", "ci_high"} <= set(r) else None
            ax.bar(x - 0.4 + width * (i + 1.5), 100 * r["synth_rate"].values, width, yerr=err, capsize=2, label=c)
        ax.set_xticks(x, hyps, rotation=20)
        ax.set_ylabel("co-occurrence rate (%)")
        ax.set_title(char)
        ax.legend(fontsize=7)
    fig.tight_layout()
    return fig
