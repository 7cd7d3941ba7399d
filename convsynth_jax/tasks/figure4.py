"""Task ``figure4``: histograms of c(i, i+k) for k = 2..5 with the fitted distributions.
Writes ``figure4_histograms.csv`` (character, k, bin_left, bin_right, density), ``figure4_fits.csv``
(character, k, distribution, params, rss, chosen, threshold) and ``figure4.png``/``.pdf``; the
script ``experiments/figure4.py`` redraws the figure from the two CSVs."""
from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import List

import numpy as np
import pandas as pd

from ..utils import atomic_path


@dataclass(frozen=True)
class Figure4Settings:
    """``conf/task/figure4.yaml``."""

    name: str = "figure4"
    ks: List[int] = field(default_factory=lambda: [2, 3, 4, 5])  # key-state granularities k


def run(cfg, out_dir: Path) -> dict:
    from ..graph import build_database
    from ..graph.build import k_step_costs, velocity_weight
    from ..stats.fits import fit_distributions
    from .build_graph import character_clip_sets
    from ..config import task_settings
    from .common import params_of

    params = params_of(cfg)
    ks = task_settings(cfg).ks
    p = params.graph
    hist_rows, fit_rows = [], []
    for char, clips in character_clip_sets(params).items():
        db = build_database(clips, params.features)
        for k in ks:
            # w_v as build_graph would choose it for this k, so each panel's threshold is the graph's
            w_v = velocity_weight(db, dataclasses.replace(p, k=int(k)))
            x = k_step_costs(db, int(k), w_v)
            fit = fit_distributions(x, choose=p.distribution, bins=p.fit_bins, seed=p.seed)
            for lo, hi, d in zip(fit.bin_edges[:-1], fit.bin_edges[1:], fit.density):
                hist_rows.append({"character": char or "all", "k": int(k), "bin_left": lo, "bin_right": hi, "density": d})
            for r in fit.table.itertuples():
                fit_rows.append({"character": char or "all", "k": int(k), "distribution": r.distribution,
                                 "params": json.dumps(list(r.params)), "rss": r.rss, "chosen": r.distribution == fit.chosen, "w_v": w_v,
                                 "threshold": fit.quantile(p.quantile, r.distribution) if r.params else np.nan})
    hist, fits = pd.DataFrame(hist_rows), pd.DataFrame(fit_rows)
    for name, df in (("figure4_histograms", hist), ("figure4_fits", fits)):
        with atomic_path(out_dir / f"{name}.csv") as tmp:
            df.to_csv(tmp, index=False)
    from ..figures import figure4_figure

    fig = figure4_figure(hist, fits)
    for ext in ("png", "pdf"):
        with atomic_path(out_dir / f"figure4.{ext}") as tmp:
            fig.savefig(tmp, dpi=120, format=ext)
    chosen = fits[fits["chosen"]]
    return {"fits": chosen[["character", "k", "distribution", "rss", "threshold"]].to_dict(orient="records")}
