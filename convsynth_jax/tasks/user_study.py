"""Task ``user_study``: Figure 6 from forced-choice counts (CSV: comparison, method_a, method_b,
preferred_a, total; default: the paper's counts). Two-sample test for equality of proportions with
continuity correction (R's prop.test) per comparison; writes a table (CSV, Markdown) and a stacked
bar chart."""
from __future__ import annotations

from pathlib import Path

import pandas as pd

from ..errors import FormatError
from ..evaluation.summaries import to_markdown
from ..stats.tests import proportion_test
from ..utils import atomic_path, write_text_atomic

PAPER_CSV = Path(__file__).resolve().parent.parent / "resources" / "user_study_paper.csv"


def analyse(df: pd.DataFrame, path=None) -> pd.DataFrame:
    need = {"comparison", "preferred_a", "total"}
    if not need <= set(df.columns):
        raise FormatError(f"user-study CSV needs columns {sorted(need)}", path, "line 1")
    rows = []
    for i, r in df.iterrows():
        a, n = int(r["preferred_a"]), int(r["total"])
        if not 0 <= a <= n or n <= 0:
            raise FormatError(f"preferred_a={a} and total={n} are inconsistent", path, f"line {i + 2}")
        t = proportion_test(a, n - a, n)
        rows.append({**r.to_dict(), "preferred_b": n - a, "share_a": a / n, "chi2": t.chi2, "df": t.df,
                     "p_value": t.p_value, "significant": t.p_value < 0.03})
    return pd.DataFrame(rows)


def run(cfg, out_dir: Path) -> dict:
    from ..plotting import user_study_figure

    src = Path(cfg.task.get("csv") or PAPER_CSV)
    if not src.is_file():
        from ..errors import MissingFileError

        raise MissingFileError("user-study CSV not found", src)
    table = analyse(pd.read_csv(src), src)
    with atomic_path(out_dir / "user_study.csv") as tmp:
        table.to_csv(tmp, index=False)
    write_text_atomic(out_dir / "user_study.md", to_markdown(table))
    fig = user_study_figure(table)
    with atomic_path(out_dir / "figure6.png") as tmp:
        fig.savefig(tmp, dpi=120, format="png")
    print("\n" + to_markdown(table[["comparison", "preferred_a", "total", "chi2", "p_value"]]))
    return {"source": str(src), "rows": table.to_dict(orient="records")}
