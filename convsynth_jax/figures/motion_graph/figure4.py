"""Figure 4 of the paper: histograms of the k-step costs c(i, i+k) with the fitted distributions.

Pure data -> matplotlib Figure; the task ``figure4`` writes the data (two CSV tables) and calls
:func:`figure4_figure`, so the figure can be redrawn from the tables alone.
"""
from __future__ import annotations

import json

from matplotlib.figure import Figure
import numpy as np
import pandas as pd
from scipy import stats


def _params(p):
    return tuple(json.loads(p)) if isinstance(p, str) else tuple(p)


def figure4_figure(hist: pd.DataFrame, fits: pd.DataFrame, show_all: bool = True):
    """One panel per (character, k).

    hist: rows (character, k, bin_left, bin_right, density), the normalized histogram of c(i, i+k);
    fits: rows (character, k, distribution, params [JSON list or tuple], rss, chosen, threshold).
    The chosen fit is drawn bold with its threshold as a dashed line; with ``show_all`` the other
    candidates are drawn thin. Returns the Figure.
    """
    chars = list(dict.fromkeys(hist["character"]))
    ks = list(dict.fromkeys(hist["k"]))
    fig = Figure(figsize=(3.2 * len(ks), 2.6 * len(chars)))
    axes = fig.subplots(len(chars), len(ks), squeeze=False)
    for (char, k), h in hist.groupby(["character", "k"], sort=False):
        ax = axes[chars.index(char)][ks.index(k)]
        ax.bar(h["bin_left"], h["density"], width=h["bin_right"] - h["bin_left"], align="edge", color="#c9b8e0",
               label="histogram")
        x = np.linspace(float(h["bin_left"].min()), float(h["bin_right"].max()), 400)
        f = fits[(fits["character"] == char) & (fits["k"] == k)]
        for r in f.itertuples():
            params = _params(r.params)
            if not params:
                continue
            chosen = bool(r.chosen)
            if not (chosen or show_all):
                continue
            with np.errstate(all="ignore"):
                y = getattr(stats, r.distribution).pdf(x, *params)
            ax.plot(x, y, lw=1.6 if chosen else 0.7, color="k" if chosen else None, alpha=1.0 if chosen else 0.6,
                    label=f"{r.distribution}{' (chosen)' if chosen else ''}")
            if chosen and np.isfinite(r.threshold):
                ax.axvline(r.threshold, color="r", lw=0.8, ls="--", label="threshold")
        top = float(h["density"].max())
        if top > 0:
            ax.set_ylim(0, 1.3 * top)
        ax.set_title(f"{char} k={k}" if char not in ("", "all") else f"k={k}", fontsize=9)
        ax.set_xlabel("c(i, i+k)", fontsize=8)
        ax.tick_params(labelsize=7)
    axes[0][0].set_ylabel("density", fontsize=8)
    handles, labels = axes[0][-1].get_legend_handles_labels()
    if handles:
        axes[0][-1].legend(handles, labels, fontsize=6, loc="upper right")
    fig.tight_layout()
    return fig
