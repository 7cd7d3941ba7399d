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
    from ..graph import build_database
    from ..graph.statistics import graph_statistics
    from .build_graph import character_clip_sets
    from ..config import task_settings
    from .common import params_of

    params = params_of(cfg)
    hist_rows, fit_rows = [], []
    for char, clips in character_clip_sets(params).items():
        db = build_database(clips, params.features)
        # w_v as build_graph would choose it for each k, so each panel's threshold is the graph's
        st = graph_statistics(db, params.graph, task_settings(cfg).ks, char or "all", build_graphs=False,
                              fit_all=True)
        hist_rows += st.histograms
        fit_rows += st.fits
    hist, fits = pd.DataFrame(hist_rows), pd.DataFrame(fit_rows)
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
