"""Task ``table2``: states and edges before and after keeping the largest strongly connected
component for k = 2, 3, 4, 5 (``task.ks``), per character (or one row set for bvh_folder).
Writes ``table2.csv`` and ``table2.md``; the ``scc_warning`` column is non-empty for a k whose largest
SCC keeps under half of the states (also logged as a warning)."""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import List

import pandas as pd

from ..evaluation.summaries import to_markdown
from ..utils import atomic_path, write_text_atomic

log = logging.getLogger(__name__)

TABLE2_COLUMNS = ["character", "k", "threshold", "states_before_scc", "edges_before_scc", "states_after_scc",
                  "edges_after_scc", "kept_state_fraction", "seconds", "scc_warning"]


@dataclass(frozen=True)
class Table2Settings:
    """``conf/task/table2.yaml``."""

    name: str = "table2"
    ks: List[int] = field(default_factory=lambda: [2, 3, 4, 5])  # key-state granularities k


def run(cfg, out_dir: Path) -> dict:
    from .build_graph import character_graph_statistics
    from ..config import task_settings
    from .common import params_of

    stats = character_graph_statistics(params_of(cfg), task_settings(cfg).ks)
    rows = [row for st in stats for row in st.table2]
    table = pd.DataFrame(rows)[TABLE2_COLUMNS]
    with atomic_path(out_dir / "table2.csv") as tmp:
        table.to_csv(tmp, index=False)
    write_text_atomic(out_dir / "table2.md", to_markdown(table))
    log.info("Table 2\n%s", to_markdown(table))
    return {"rows": table.to_dict(orient="records")}
