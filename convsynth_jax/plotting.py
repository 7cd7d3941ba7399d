"""Pure data -> matplotlib Figure helpers for the paper's tables and figures."""
from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def cooccurrence_figure(table):
    """Bars: matched rate in audio windows next to the chance rate in random windows (Table 1)."""
    chars = list(dict.fromkeys(table["character"]))
    fig, axes = plt.subplots(1, max(1, len(chars)), figsize=(5 * max(1, len(chars)), 3.2), squeeze=False)
    for ax, c in zip(axes[0], chars):
        g = table[table["character"] == c]
        x = np.arange(len(g))
        ax.bar(x - 0.2, 100 * g["rate"], 0.4, label="audio windows")
        ax.bar(x + 0.2, 100 * g["chance_rate"], 0.4, label="random windows", color="grey")
        ax.set_xticks(x, g["hypothesis"], rotation=20)
        ax.set_ylabel("matched (%)")
        ax.set_title(c)
        ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


def user_study_figure(table):
    """Figure 6: one stacked horizontal bar per comparison (share preferring A | B), * if p < 0.03."""
    fig, ax = plt.subplots(figsize=(7, 0.6 * len(table) + 1))
    y = np.arange(len(table))[::-1]
    a = 100 * table["share_a"].to_numpy()
    ax.barh(y, a, color="#4f6fa8")
    ax.barh(y, 100 - a, left=a, color="#d9a441")
    for yi, ai, r in zip(y, a, table.itertuples()):
        ax.text(ai / 2, yi, f"{ai:.0f}%", ha="center", va="center", color="w", fontsize=8)
        ax.text(ai + (100 - ai) / 2, yi, f"{100 - ai:.0f}%", ha="center", va="center", fontsize=8)
        star = " *" if r.significant else ""
        ax.text(-1, yi, f"{getattr(r, 'method_a', r.comparison)}{star}", ha="right", va="center", fontsize=8)
        ax.text(101, yi, f"{getattr(r, 'method_b', '')}", ha="left", va="center", fontsize=8)
    ax.set_xlim(0, 100)
    ax.set_yticks([])
    ax.set_xlabel("share of answers (%)")
    fig.tight_layout()
    return fig


# Figure 4 (cost histograms with fitted curves) lives in convsynth_jax.graph.figures.
