"""The grouped bars of the co-occurrence ablation, shared by its chart (``loo.ablation_figure``)
and the chart beside the paper (``paper.ablation_ci_figure``): per hypothesis, the ground truth's
bar and then one bar per condition, side by side in 0.8 of the unit between hypotheses."""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pandas as pd


class ConditionBars(NamedTuple):
    """One character's bars. ``x``: (hypotheses,) tick positions; ``truth``: the first row per
    hypothesis (its gt_* columns are the ground truth's), in ``hypotheses`` order; ``conditions``:
    (condition, its rows indexed by hypothesis, (hypotheses,) bar positions) in first-seen order."""

    x: np.ndarray
    hypotheses: list
    width: float
    truth: pd.DataFrame
    truth_x: np.ndarray
    conditions: list


def condition_bars(g: pd.DataFrame) -> ConditionBars:
    """The bars of ``g``, one character's rows (hypothesis, condition, gt_rate, synth_rate, ...)."""
    hyps = list(dict.fromkeys(g["hypothesis"]))
    conds = list(dict.fromkeys(g["condition"]))
    width = 0.8 / (len(conds) + 1)
    x = np.arange(len(hyps))
    truth = g.groupby("hypothesis").first().reindex(hyps)
    rows = [(c, g[g["condition"] == c].set_index("hypothesis").reindex(hyps), x - 0.4 + width * (i + 1.5))
            for i, c in enumerate(conds)]
    return ConditionBars(x, hyps, width, truth, x - 0.4 + width / 2, rows)
