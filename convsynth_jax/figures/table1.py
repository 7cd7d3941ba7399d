"""Table 1 of the paper as a chart: matched rate in audio windows beside the chance rate."""
from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure


def table1_figure(table) -> Figure:
    """Bars: matched rate in audio windows next to the chance rate in random windows (Table 1)."""
    chars = list(dict.fromkeys(table["character"]))
    fig = Figure(figsize=(5 * max(1, len(chars)), 3.2))
    axes = fig.subplots(1, max(1, len(chars)), squeeze=False)
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
