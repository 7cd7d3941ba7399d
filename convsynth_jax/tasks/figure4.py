"""Task ``figure4``: histograms of c(i, i+k) for k = 2..5 with the fitted distributions.
Writes ``figure4_histograms.csv`` (character, k, bin_left, bin_right, density), ``figure4_fits.csv``
(character, k, distribution, params, rss, chosen, threshold) and ``figure4.png``/``.pdf``; the
script ``experiments/paper/figure4.py`` redraws the figure from the two CSVs."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import List

import pandas as pd

from ..utils import atomic_path


@dataclass(frozen=True)
class Figure4Settings:
    """``conf/task/figure4.yaml``."""

    name: str = "figure4"
    ks: List[int] = field(default_factory=lambda: [2, 3, 4, 5])  # key-state granularities k


def run(cfg, out_dir: Path) -> dict:
    from .build_graph import character_graph_statistics
    from ..config import task_settings
    from .common import params_of

    params = params_of(cfg)
    # w_v as build_graph would choose it for each k, so each panel's threshold is the graph's
    stats = character_graph_statistics(params, task_settings(cfg).ks, build_graphs=False, fit_all=True)
    hist = pd.DataFrame([row for st in stats for row in st.histograms])
    fits = pd.DataFrame([row for st in stats for row in st.fits])
    for name, df in (("figure4_histograms", hist), ("figure4_fits", fits)):
        with atomic_path(out_dir / f"{name}.csv") as tmp:
            df.to_csv(tmp, index=False)
    from ..figures import save_figure
    from ..figures.motion_graph import figure4_figure

    fig = figure4_figure(hist, fits)
    for ext in ("png", "pdf"):
        save_figure(fig, out_dir / f"figure4.{ext}", dpi=120)
    chosen = fits[fits["chosen"]]
    return {"fits": chosen[["character", "k", "distribution", "rss", "threshold"]].to_dict(orient="records")}
