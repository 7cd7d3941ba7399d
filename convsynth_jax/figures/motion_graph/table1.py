"""Table 1 of the paper as a chart: matched rate in audio windows beside the chance rate."""
from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from ..panels import label_panel, panel_row


def rate_errors(rate, low, high) -> np.ndarray | None:
    """(2, N) error-bar lengths in percent below/above each rate from its interval columns, or None
    when the interval is absent; NaN bounds draw no bar."""
    if low is None or high is None:
        return None
    rate, low, high = (np.asarray(x, dtype=np.float64) for x in (rate, low, high))
    err = 100 * np.vstack([rate - low, high - rate])
    return np.where(np.isfinite(err), np.maximum(err, 0.0), 0.0)


def table1_figure(table) -> Figure:
    """Bars: matched rate in audio windows next to the chance rate in random windows (Table 1), with
    the Wilson intervals (ci_low/ci_high, chance_ci_low/chance_ci_high) as error bars when the table
    has them; a row without a chance baseline (chance_method ``none``) draws no chance bar."""
    chars = list(dict.fromkeys(table["character"]))
    fig, axes = panel_row(len(chars), 5, 3.2)
    for ax, c in zip(axes, chars):
        g = table[table["character"] == c]
        x = np.arange(len(g))
        err = rate_errors(g["rate"], g.get("ci_low"), g.get("ci_high"))
        ax.bar(x - 0.2, 100 * g["rate"], 0.4, yerr=err, capsize=2 if err is not None else 0, label="audio windows")
        cerr = rate_errors(g["chance_rate"], g.get("chance_ci_low"), g.get("chance_ci_high"))
        ax.bar(x + 0.2, 100 * g["chance_rate"].fillna(0.0), 0.4, yerr=cerr, capsize=2 if cerr is not None else 0,
               label="random windows", color="grey")
        labels = list(g["hypothesis"])
        if "chance_method" in g:  # say which baseline a row used when it is not the usual one
            labels = [h if m == "away" else f"{h}\n({m})" for h, m in zip(labels, g["chance_method"])]
        ax.set_xticks(x, labels, rotation=20)
        label_panel(ax, c, "matched (%)")
    fig.tight_layout()
    return fig
