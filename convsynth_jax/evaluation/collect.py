"""Merge the per-job results of a Hydra multirun into one table.

Each leave-one-out job writes ``cases.csv`` into its own output directory. A job that crashed or
never wrote its table is still recorded (status ``error``, with its overrides), so a failing job
never silently disappears from the study.
"""
from __future__ import annotations

import json
import logging
from pathlib import Path

import pandas as pd
import yaml

from ..errors import MissingFileError
from . import summaries

log = logging.getLogger(__name__)


def _job_dirs(root: Path) -> list[Path]:
    """Directories that hold a Hydra job (they have .hydra/overrides.yaml) or a cases.csv."""
    found = {p.parent.parent for p in root.rglob(".hydra/overrides.yaml")}
    found |= {p.parent for p in root.rglob("cases.csv")}
    # hidden folders other than Hydra's are partial results (a results store's unfinished entries)
    return sorted(d for d in found if not any(part.startswith(".") for part in d.relative_to(root).parts))


def _overrides(job: Path) -> dict:
    f = job / ".hydra" / "overrides.yaml"
    if not f.is_file():
        return {}
    out = {}
    for item in yaml.safe_load(f.read_text()) or []:
        if "=" in item:
            k, v = item.split("=", 1)
            out[k.lstrip("+~")] = v
    return out


def collect_cases(root: str | Path) -> pd.DataFrame:
    """All test cases below ``root`` (a multirun directory or a single job directory)."""
    root = Path(root)
    if not root.exists():
        raise MissingFileError("results directory not found", root)
    frames = []
    for job in _job_dirs(root):
        cases = job / "cases.csv"
        if cases.is_file():
            df = pd.read_csv(cases)
            df["job_dir"] = str(job.relative_to(root)) if job != root else "."
            frames.append(df)
            continue
        ov = _overrides(job)
        err = "job wrote no cases.csv"
        summ = job / "summary.json"
        if summ.is_file():
            try:
                err = json.loads(summ.read_text()).get("error", err)
            except json.JSONDecodeError:
                pass
        log.warning("%s: %s", job, err)
        frames.append(pd.DataFrame([{
            "fold": pd.to_numeric(ov.get("fold"), errors="coerce"), "condition": ov.get("condition"),
            "status": "error", "error": err, "success": False, "job_dir": str(job.relative_to(root)),
        }]))
    if not frames:
        return pd.DataFrame(columns=["fold", "condition", "status", "success"])
    return pd.concat(frames, ignore_index=True)


def write_collected(cases: pd.DataFrame, out_dir: str | Path) -> dict:
    """Write the merged table and the summary tables (CSV + Markdown). Returns a summary dict."""
    from ..utils import write_text_atomic

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    tables = {
        "all_cases": cases,
        "success_rates": summaries.success_rates(cases[cases.get("status", "ok") != "error"]) if "character" in cases else pd.DataFrame(),
        "table3": summaries.timing_table(cases) if "synthesis_seconds" in cases else pd.DataFrame(),
        "cooccurrence_by_condition": summaries.cooccurrence_by_condition(cases) if "character" in cases else pd.DataFrame(),
        "quality_by_condition": summaries.quality_by_condition(cases) if "character" in cases else pd.DataFrame(),
    }
    for name, df in tables.items():
        from ..utils import atomic_path

        with atomic_path(out_dir / f"{name}.csv") as tmp:
            df.to_csv(tmp, index=False)
        if name != "all_cases":
            write_text_atomic(out_dir / f"{name}.md", summaries.to_markdown(df))
    n_err = int((cases.get("status") == "error").sum()) if "status" in cases else 0
    return {"num_rows": int(len(cases)), "num_failed_jobs": n_err, "tables": sorted(tables)}
