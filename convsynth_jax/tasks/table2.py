"""Task ``table2``: states and edges before and after keeping the largest strongly connected
component for k = 2, 3, 4, 5 (``task.ks``), per character (or one row set for bvh_folder).
Writes ``table2.csv`` and ``table2.md``; the ``scc_warning`` column is non-empty for a k whose largest
SCC keeps under half of the states (also logged as a warning)."""
from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import List

import pandas as pd

from ..evaluation.summaries import to_markdown
from ..utils import atomic_path, write_text_atomic

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Table2Settings:
    """``conf/task/table2.yaml``."""

    name: str = "table2"
    ks: List[int] = field(default_factory=lambda: [2, 3, 4, 5])  # key-state granularities k


def run(cfg, out_dir: Path) -> dict:
    from ..graph import build_database, build_graph
    from .build_graph import character_clip_sets
    from ..config import task_settings
    from .common import params_of

    params = params_of(cfg)
    ks = task_settings(cfg).ks
    rows = []
    for char, clips in character_clip_sets(params).items():
        db = build_database(clips, params.features)
        for k in ks:
            g = build_graph(db, dataclasses.replace(params.graph, k=int(k)))
            m = g.meta
            rows.append({"character": char or "all", "k": int(k), "threshold": m["threshold"],
                         "states_before_scc": m["num_states_before_scc"], "edges_before_scc": m["num_edges_before_scc"],
                         "states_after_scc": m["num_states"], "edges_after_scc": m["num_edges"],
                         "kept_state_fraction": m["num_states"] / m["num_states_before_scc"], "seconds": m["seconds"],
                         "scc_warning": m.get("scc_warning", "")})
    table = pd.DataFrame(rows)
    with atomic_path(out_dir / "table2.csv") as tmp:
        table.to_csv(tmp, index=False)
    write_text_atomic(out_dir / "table2.md", to_markdown(table))
    log.info("Table 2\n%s", to_markdown(table))
    return {"rows": table.to_dict(orient="records")}
