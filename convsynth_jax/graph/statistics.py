"""Table 2 and Figure 4 of the paper from one motion database, for several k: the graph's states and
edges before and after the largest strongly connected component, and the distribution of the k-step
costs c(i, i+k) with the fitted curve(s) and the threshold.

Computed here, once, for the tasks ``main`` (the report's Table 2 and Figure 4, on the training
sessions of a fold), ``table2`` and ``figure4`` (on the whole corpus); each task writes the columns it
reports. Rows are plain Python values (JSON-ready, so ``main`` can cache them).
"""
from __future__ import annotations

import dataclasses
import json
from typing import NamedTuple

import numpy as np

from ..errors import ConfigError
from ..stats.fits import fit_distributions
from .build import build_graph, k_step_costs, velocity_weight
from .database import MotionDatabase
from .params import GraphParams


class GraphStatistics(NamedTuple):
    """Rows (dicts) per character and k.

    table2: character, k, threshold, states/edges before and after the SCC, kept_state_fraction,
        key_fraction, distribution, seconds (construction wall time), scc_warning; empty when the
        graphs were not built;
    histograms: character, k, bin_left, bin_right, density (the normalized histogram of c(i, i+k));
    fits: character, k, distribution, params (JSON list), rss, chosen, w_v, threshold (the chosen fit
        only, rss NaN, unless every candidate was fitted).
    """

    table2: list
    histograms: list
    fits: list


def graph_statistics(db: MotionDatabase, params: GraphParams, ks, character: str = "all", graphs: dict | None = None,
                     build_graphs: bool = True, fit_all: bool = False) -> GraphStatistics:
    """Table 2 rows and Figure 4 data of ``db`` for each k in ``ks`` (``params`` with its k replaced).

    With ``build_graphs`` each k's graph is built (or taken from ``graphs``, k -> MotionGraph, e.g. the
    fitted model's), its size gives the Table 2 row, and its w_v, chosen distribution and threshold the
    Figure 4 fit. ``fit_all`` (the ``figure4`` task) fits every candidate distribution to c(i, i+k)
    (``stats.fits.fit_distributions``, on the same seeded sample as the graph's fit, so the chosen
    one's threshold is the graph's) and takes the histogram of that fit; without graphs, w_v is the
    one ``build_graph`` would choose for that k."""
    if not (build_graphs or fit_all):
        raise ConfigError("Figure 4 statistics need the graphs' fits or fit_all", where="graph_statistics")
    table2, hist, fits = [], [], []
    graphs = graphs or {}
    for k in (int(k) for k in ks):
        pk = dataclasses.replace(params, k=k)
        g = graphs.get(k) if build_graphs else None
        if build_graphs and g is None:
            g = build_graph(db, pk)
        w_v = float(g.meta["w_v"]) if g is not None else velocity_weight(db, pk)
        x = k_step_costs(db, k, w_v)
        if g is not None:
            m = g.meta
            table2.append({"character": character, "k": k, "threshold": m["threshold"],
                           "states_before_scc": m["num_states_before_scc"], "edges_before_scc": m["num_edges_before_scc"],
                           "states_after_scc": m["num_states"], "edges_after_scc": m["num_edges"],
                           "kept_state_fraction": m["num_states"] / m["num_states_before_scc"],
                           "key_fraction": m["key_fraction"], "distribution": m["distribution"],
                           "seconds": m.get("seconds"), "scc_warning": m.get("scc_warning", "")})
        if fit_all:
            fit = fit_distributions(x, choose=params.distribution, bins=params.fit_bins, seed=params.seed)
            edges, density = fit.bin_edges, fit.density
            for r in fit.table.itertuples():
                fits.append({"character": character, "k": k, "distribution": r.distribution,
                             "params": json.dumps(list(r.params)), "rss": r.rss, "chosen": r.distribution == fit.chosen,
                             "w_v": w_v, "threshold": fit.quantile(params.quantile, r.distribution) if r.params else np.nan})
        else:
            density, edges = np.histogram(x[np.isfinite(x)], bins=params.fit_bins, density=True)
            m = g.meta
            fits.append({"character": character, "k": k, "distribution": m["distribution"],
                         "params": json.dumps(list(m["distribution_params"])), "rss": np.nan, "chosen": True,
                         "w_v": w_v, "threshold": m["threshold"]})
        hist += [{"character": character, "k": k, "bin_left": float(lo), "bin_right": float(hi), "density": float(d)}
                 for lo, hi, d in zip(edges[:-1], edges[1:], density)]
    return GraphStatistics(table2, hist, fits)
