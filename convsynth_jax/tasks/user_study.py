"""Task ``user_study``: Figure 6 from forced-choice counts (CSV: comparison, method_a, method_b,
preferred_a, total; default: the paper's counts). Two-sample test for equality of proportions with
continuity correction (R's prop.test) and the exact binomial test per comparison
(:func:`convsynth_jax.study.analyze.forced_choice_table`); writes a table (CSV, Markdown) and a
stacked bar chart."""
from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import pandas as pd

from ..errors import FormatError
from ..evaluation.summaries import to_markdown
from ..study.analyze import forced_choice_table as analyse  # noqa: F401  (the tests' and scripts' name)
from ..utils import atomic_path, write_text_atomic

log = logging.getLogger(__name__)

PAPER_CSV = Path(__file__).resolve().parent.parent / "resources" / "user_study_paper.csv"


@dataclass(frozen=True)
class UserStudySettings:
    """``conf/task/user_study.yaml``."""

    name: str = "user_study"
    csv: Optional[str] = None           # the study's responses (None: the paper's, shipped)


def run(cfg, out_dir: Path) -> dict:
    from ..figures import save_figure
    from ..figures.motion_graph import figure6_figure

    from ..config import task_settings

    src = Path(task_settings(cfg).csv or PAPER_CSV)
    if not src.is_file():
        from ..errors import MissingFileError

        raise MissingFileError("user-study CSV not found", src)
    try:
        raw = pd.read_csv(src)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as e:
        raise FormatError(f"not a readable CSV ({e})", src) from None
    from .common import params_of

    table = analyse(raw, src, alpha=params_of(cfg).stats.significance)
    with atomic_path(out_dir / "user_study.csv") as tmp:
        table.to_csv(tmp, index=False)
    write_text_atomic(out_dir / "user_study.md", to_markdown(table))
    save_figure(figure6_figure(table), out_dir / "figure6.png", dpi=120)
    log.info("%s", "\n" + to_markdown(table[["comparison", "preferred_a", "total", "chi2", "p_value"]]))
    return {"source": str(src), "figure": "figure6.png", "rows": table.to_dict(orient="records")}
