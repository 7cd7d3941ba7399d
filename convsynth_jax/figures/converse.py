"""A converse sweep over conditions as a figure: per speaker and condition, the constraints of
condition ``all`` split into met, checked but not met, and switched off (``task=collect``'s
``converse_by_condition.csv``, :func:`convsynth_jax.evaluation.summaries.converse_constraints_met`)."""
from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.figure import Figure


def converse_conditions_figure(table: pd.DataFrame) -> Figure:
    """Stacked bars, one per condition, grouped by speaker: shares of the reference condition's
    constraints met (dark), checked but not met (light) and switched off by the condition (hatched);
    every bar of a speaker has the same denominator, written above it."""
    speakers = list(dict.fromkeys(table["speaker"]))
    fig = Figure(figsize=(max(4.0, 2.4 * len(speakers)), 3.2), layout="constrained")
    axes = fig.subplots(1, len(speakers), sharey=True, squeeze=False)[0]
    for ax, who in zip(axes, speakers):
        g = table[table["speaker"] == who]
        x = np.arange(len(g))
        n = g["constraints"].to_numpy(float)
        safe = np.where(n > 0, n, 1.0)
        met = g["met"].to_numpy(float) / safe
        missed = (g["on"].to_numpy(float) - g["met"].to_numpy(float)) / safe
        off = g["switched_off"].to_numpy(float) / safe
        ax.bar(x, 100 * met, color="#3b6ea8", label="met")
        ax.bar(x, 100 * missed, bottom=100 * met, color="#b7cbe3", label="checked, not met")
        ax.bar(x, 100 * off, bottom=100 * (met + missed), color="white", edgecolor="0.5", hatch="//",
               label="switched off")
        for i, (k, tot) in enumerate(zip(g["met"], g["constraints"])):
            ax.text(i, 102, f"{int(k)}/{int(tot)}", ha="center", fontsize=7)
        ax.set_xticks(x, g["condition"])
        char = g["character"].iloc[0] if "character" in g else ""
        ax.set_title(f"{who} ({char})" if char else str(who), fontsize=9)
        ax.set_ylim(0, 112)
    axes[0].set_ylabel("constraints of condition all (%)")
    axes[-1].legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    return fig
