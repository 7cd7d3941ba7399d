"""The benchmark's leaderboard as a figure: one panel per (scope, metric), a bar per system with
its bootstrap 95% interval (``convsynth task=benchmark``, ``leaderboard.csv``)."""
from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from ..evaluation.benchmark import NOISE_FLOOR


def leaderboard_figure(board: pd.DataFrame, ncols: int = 5) -> Figure:
    """board: ``leaderboard.csv`` (system, scope, metric, value, ci_low, ci_high, rank). The noise
    floor (the ground truth's odd against its even windows) is a dashed line where it has a value."""
    floor = board[board["system"] == NOISE_FLOOR].set_index(["scope", "metric"])["value"]
    board = board[board["system"] != NOISE_FLOOR]
    panels = list(dict.fromkeys(zip(board["scope"], board["metric"])))
    nrows = max(1, int(np.ceil(len(panels) / ncols)))
    fig = Figure(figsize=(3.2 * ncols, 2.6 * nrows), layout="constrained")
    systems = list(dict.fromkeys(board["system"]))
    colors = {s: f"C{i}" for i, s in enumerate(systems)}
    for i, (scope, metric) in enumerate(panels):
        ax = fig.add_subplot(nrows, ncols, i + 1)
        g = board[(board["scope"] == scope) & (board["metric"] == metric)]
        x = np.arange(len(g))
        v = g["value"].to_numpy(float)
        lo = np.clip(v - g["ci_low"].to_numpy(float), 0, None)
        hi = np.clip(g["ci_high"].to_numpy(float) - v, 0, None)
        err = np.nan_to_num(np.vstack([lo, hi]))
        ax.bar(x, np.nan_to_num(v), yerr=err, color=[colors[s] for s in g["system"]], capsize=2)
        ax.set_xticks(x, [s.replace("_", "\n") for s in g["system"]], fontsize=6)
        if (scope, metric) in floor.index and np.isfinite(floor[(scope, metric)]):
            ax.axhline(float(floor[(scope, metric)]), color="0.4", ls="--", lw=0.8, label="GT odd vs even")
            ax.legend(fontsize=5, loc="upper right")
        ax.set_title(f"{metric} ({scope})", fontsize=8)
        ax.tick_params(axis="y", labelsize=6)
    return fig
