"""Task ``table2``: states and edges before and after keeping the largest strongly connected
component for k = 2, 3, 4, 5 (``task.ks``), per character (or one row set for bvh_folder).
Writes ``table2.csv`` and ``table2.md``; the ``scc_warning`` column is non-empty for a k whose largest
SCC keeps under half of the states (also logged as a warning)."""
from __future__ import annotations

import logging
from pathlib import Path

import pandas as pd

from ..evaluation.summaries import to_markdown
from ..utils import atomic_path, write_text_atomic

log = logging.getLogger(__name__)

TABLE2_COLUMNS = ["character", "k", "threshold", "states_before_scc", "edges_before_scc", "states_after_scc",
                  "edges_after_scc", "kept_state_fraction", "seconds", "scc_warning"]


def run(cfg, out_dir: Path) -> dict:
    from ..graph import build_database
    from ..graph.statistics import graph_statistics
    from .build_graph import character_clip_sets
    from .common import params_of

    params = params_of(cfg)
    rows = []
    for char, clips in character_clip_sets(params).items():
        db = build_database(clips, params.features)
        rows += graph_statistics(db, params.graph, cfg.task.get("ks", [2, 3, 4, 5]), char or "all").table2
    table = pd.DataFrame(rows)[TABLE2_COLUMNS]
    with atomic_path(out_dir / "table2.csv") as tmp:
        table.to_csv(tmp, index=False)
    write_text_atomic(out_dir / "table2.md", to_markdown(table))
    log.info("Table 2\n%s", to_markdown(table))
    return {"rows": table.to_dict(orient="records")}
