"""Task ``user_study``: Figure 6 from forced-choice counts (CSV: comparison, method_a, method_b,
preferred_a, total; default: the paper's counts). Two-sample test for equality of proportions with
continuity correction (R's prop.test) per comparison; writes a table (CSV, Markdown) and a stacked
bar chart."""
from __future__ import annotations

import logging
from pathlib import Path

import pandas as pd

from ..errors import FormatError
from ..evaluation.summaries import to_markdown
from ..stats.hypothesis import proportion_test
from ..utils import atomic_path, write_text_atomic

log = logging.getLogger(__name__)

PAPER_CSV = Path(__file__).resolve().parent.parent / "resources" / "user_study_paper.csv"


def analyse(df: pd.DataFrame, path=None, alpha: float = 0.03) -> pd.DataFrame:
    """One row per comparison: the input columns plus preferred_b, share_a, chi2, df, p_value and
    significant (p < alpha; the paper stars p < 0.03). Bad rows raise FormatError naming the line."""
    need = {"comparison", "preferred_a", "total"}
    if not need <= set(df.columns):
        raise FormatError(f"user-study CSV needs columns {sorted(need)}, has {list(df.columns)}", path, "line 1")
    rows = []
    for i, r in df.reset_index(drop=True).iterrows():
        try:
            a_f, n_f = float(r["preferred_a"]), float(r["total"])
        except (TypeError, ValueError):
            a_f = n_f = float("nan")
        if not (a_f == a_f and n_f == n_f) or a_f != int(a_f) or n_f != int(n_f):
            raise FormatError(f"preferred_a and total must be integers, got {r['preferred_a']!r}, {r['total']!r}",
                              path, f"line {i + 2}")
        a, n = int(a_f), int(n_f)
        if not 0 <= a <= n or n <= 0:
            raise FormatError(f"preferred_a={a} and total={n} are inconsistent (need 0 <= preferred_a <= total)",
                              path, f"line {i + 2}")
        t = proportion_test(a, n - a, n)
        rows.append({**r.to_dict(), "preferred_b": n - a, "share_a": a / n, "chi2": t.chi2, "df": t.df,
                     "p_value": t.p_value, "significant": bool(t.p_value < alpha)})
    return pd.DataFrame(rows)


def run(cfg, out_dir: Path) -> dict:
    from ..figures import save_figure
    from ..figures.motion_graph import figure6_figure

    src = Path(cfg.task.get("csv") or PAPER_CSV)
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
