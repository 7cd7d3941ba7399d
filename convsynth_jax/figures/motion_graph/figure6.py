"""Figure 6 of the paper: forced-choice user-study shares per comparison, starred when significant."""
from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure


def figure6_figure(table) -> Figure:
    """Figure 6: one stacked horizontal bar per comparison (share preferring A | B), * if p < 0.03."""
    fig = Figure(figsize=(7, 0.6 * len(table) + 1))
    ax = fig.subplots()
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
