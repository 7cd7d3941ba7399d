"""Merge the per-job results of a Hydra multirun into tables, for every sweep the project makes.

A job writes its results and ``summary.json`` (with the task's name) into its own output folder;
what it writes depends on its task (:data:`JOB_KINDS`): leave-one-out (``task=loo``, and the main
job) ``cases.csv``, ``task=converse`` ``report.json``, ``task=benchmark`` ``leaderboard.csv``,
``task=walktalk_eval`` ``walktalk_eval_summary.csv``, ``task=cdbn_eval`` ``table_head.csv``. A job
is read by the kind its summary names (else its Hydra config, else the files it wrote), and failed
when its summary says so or its kind's file is missing. A failed job is still recorded (status
``error``, with its overrides), so it never silently disappears from the study.

:func:`collect_sweep` returns one table per kind (rows of every job, with the sweep's axes, the
overrides that differ between jobs, as columns) and the jobs table; :func:`sweep_tables` reduces
them to the summary tables (``evaluation.summaries``) and names the main one.
"""
from __future__ import annotations

import json
import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import pandas as pd
import yaml

from ..errors import MissingFileError
from . import summaries

log = logging.getLogger(__name__)


def _job_dirs(root: Path) -> list[Path]:
    """Directories that hold a Hydra job (they have .hydra/overrides.yaml), a summary.json or a cases.csv."""
    found = {p.parent.parent for p in root.rglob(".hydra/overrides.yaml")}
    found |= {p.parent for p in root.rglob("cases.csv")}
    found |= {p.parent for p in root.rglob("summary.json")}
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


def _job_config(job: Path) -> dict:
    f = job / ".hydra" / "config.yaml"
    try:
        return (yaml.safe_load(f.read_text()) or {}) if f.is_file() else {}
    except yaml.YAMLError:
        return {}


def _summary(job: Path) -> dict:
    f = job / "summary.json"
    if not f.is_file():
        return {}
    try:
        return json.loads(f.read_text())
    except json.JSONDecodeError:
        return {"success": False, "error": f"unreadable {f.name}"}


# ------------------------------------------------------------------------------------------ job kinds
def _read_loo(job: Path, config: dict) -> dict:
    return {"cases": pd.read_csv(job / "cases.csv")}


def _kinds_off(config: dict, condition: str) -> list[str]:
    """The constraint kinds a condition switches off: from the job's config (the system's condition
    switches) when it has one, else from the registry's condition names (``no_lr``: LR; ``none``: every
    kind with a switch)."""
    from ..annotate.kinds import constraint_kinds

    switches = (((config.get("system") or {}).get("conditions") or {}).get(condition))
    kinds = constraint_kinds()
    if switches is not None:
        return [k.name for k in kinds if not k.enabled(switches)]
    if condition == "none":
        return [k.name for k in kinds if k.switch is not None]
    return [k.name for k in kinds if k.condition_off == condition]


def _read_converse(job: Path, config: dict) -> dict:
    """One row per speaker (``converse_speakers``) and one per constraint the checker judged over the
    whole conversation (``converse_constraints``: kind, start and end frame, met)."""
    r = json.loads((job / "report.json").read_text())
    cond = str(r.get("condition", "all"))
    off = _kinds_off(config, cond)
    speakers, constraints = [], []
    for who, ch in r.get("characters", {}).items():
        base = {"condition": cond, "speaker": who, "character": ch.get("character")}
        total = (ch.get("checker") or {}).get("total") or {}
        speakers.append({**base, "success": bool(ch.get("success")), "kinds_off": ",".join(off),
                         "constraints_checked": total.get("total"), "constraints_met": total.get("met"),
                         "windows": len(ch.get("windows", [])), "search_seconds": ch.get("search_seconds"),
                         "synthetic_transitions": ch.get("num_synthetic_transitions"),
                         "failure": ch.get("failure") or ""})
        for d in total.get("constraints", []):
            constraints.append({**base, "kind": d["kind"], "start": d["start"], "end": d["end"], "met": bool(d["met"])})
    cols = ["condition", "speaker", "character", "kind", "start", "end", "met"]
    return {"converse_speakers": pd.DataFrame(speakers), "converse_constraints": pd.DataFrame(constraints, columns=cols)}


def _read_csv(name: str, table: str) -> Callable:
    def read(job: Path, config: dict) -> dict:
        return {table: pd.read_csv(job / name)}
    return read


def _read_cdbn(job: Path, config: dict) -> dict:
    out = {"cdbn_head": pd.read_csv(job / "table_head.csv")}
    for f, t in (("table_gestures.csv", "cdbn_gestures"), ("table_hands.csv", "cdbn_hands")):
        if (job / f).is_file():
            out[t] = pd.read_csv(job / f)
    return out


@dataclass(frozen=True)
class JobKind:
    """What a job of one task writes: ``file`` (its absence means the job failed) and ``read``
    (job folder, job config -> tables by name)."""

    tasks: tuple
    file: str
    read: Callable = field(repr=False)


JOB_KINDS = {
    "loo": JobKind(("loo", "main"), "cases.csv", _read_loo),
    "converse": JobKind(("converse",), "report.json", _read_converse),
    "benchmark": JobKind(("benchmark",), "leaderboard.csv", _read_csv("leaderboard.csv", "leaderboard")),
    "walktalk": JobKind(("walktalk_eval",), "walktalk_eval_summary.csv", _read_csv("walktalk_eval_summary.csv", "walktalk")),
    "cdbn": JobKind(("cdbn_eval",), "table_head.csv", _read_cdbn),
}


def job_kind(job: Path, summary: dict, config: dict) -> str | None:
    """The kind of a job: by the task its summary (else its config) names, else by the files it wrote."""
    task = summary.get("task") or (config.get("task") or {}).get("name")
    for name, k in JOB_KINDS.items():
        if task in k.tasks:
            return name
    if task is None:
        for name, k in JOB_KINDS.items():
            if (job / k.file).is_file():
                return name
    return None


@dataclass
class Sweep:
    """A collected sweep: ``jobs`` (one row per job: job_dir, kind, status, error, the overrides),
    ``axes`` (the overrides that differ between jobs) and ``tables`` (per kind's table name, the rows of
    every job that wrote it, with job_dir and the axes as columns)."""

    root: Path
    jobs: pd.DataFrame
    axes: list
    tables: dict

    @property
    def kinds(self) -> list[str]:
        return sorted(set(self.jobs["kind"].dropna())) if len(self.jobs) else []

    @property
    def num_failed(self) -> int:
        return int((self.jobs["status"] == "error").sum()) if len(self.jobs) else 0


def _axis_column(key: str, taken) -> str:
    """The column of a sweep axis: its last dotted part (``task.condition`` -> ``condition``) unless a
    table already has that column, then the whole key."""
    short = key.rsplit(".", 1)[-1]
    return key if short in taken else short


def collect_sweep(root: str | Path) -> Sweep:
    """Every job below ``root`` (a multirun folder or a single job folder), read by its kind."""
    root = Path(root)
    if not root.exists():
        raise MissingFileError("results directory not found", root)
    jobs, per_job = [], []
    for job in _job_dirs(root):
        rel = str(job.relative_to(root)) if job != root else "."
        summary, config, ov = _summary(job), _job_config(job), _overrides(job)
        kind = job_kind(job, summary, config)
        row = {"job_dir": rel, "kind": kind, "task": summary.get("task") or (config.get("task") or {}).get("name"),
               "status": "ok", "error": "", **ov}
        tables = {}
        if kind is None:
            row.update(status="error", error=summary.get("error") or "job wrote no results of a known kind "
                       f"({', '.join(k.file for k in JOB_KINDS.values())}) and no summary naming its task")
        elif not (job / JOB_KINDS[kind].file).is_file():
            row.update(status="error", error=summary.get("error") or f"job wrote no {JOB_KINDS[kind].file}")
        else:
            try:
                tables = JOB_KINDS[kind].read(job, config)
            except (OSError, ValueError, KeyError) as e:
                row.update(status="error", error=f"cannot read the job's results: {type(e).__name__}: {e}")
            if summary.get("success") is False:
                row.update(status="error", error=summary.get("error") or "the job's summary says it failed")
        if row["status"] == "error":
            log.warning("%s: %s", job, row["error"])
        jobs.append(row)
        per_job.append((rel, ov, tables))
    jobs_df = pd.DataFrame(jobs, columns=None if jobs else ["job_dir", "kind", "task", "status", "error"])
    override_keys = sorted({k for _, ov, _ in per_job for k in ov})
    axes = [k for k in override_keys if jobs_df[k].astype(str).nunique(dropna=False) > 1] if len(jobs_df) else []
    merged: dict[str, list] = {}
    for rel, ov, tables in per_job:
        for name, df in tables.items():
            df = df.copy()
            for k in axes:
                col = _axis_column(k, df.columns)
                if col not in df:
                    df[col] = ov.get(k)
            df["job_dir"] = rel
            merged.setdefault(name, []).append(df)
    return Sweep(root, jobs_df, axes, {n: pd.concat(fs, ignore_index=True) for n, fs in merged.items()})


def collect_cases(root: str | Path, sweep: Sweep | None = None) -> pd.DataFrame:
    """All leave-one-out test cases below ``root`` (one row per window x character x condition), with a
    row of status ``error`` for each leave-one-out job that failed or wrote nothing. ``sweep``: the
    sweep already collected from ``root``."""
    sw = sweep if sweep is not None else collect_sweep(root)
    frames = [sw.tables["cases"]] if "cases" in sw.tables else []
    have = set(sw.tables["cases"]["job_dir"]) if "cases" in sw.tables else set()
    for r in sw.jobs.to_dict("records"):  # a failed job that wrote no table: one row saying why
        if r["status"] == "error" and (pd.isna(r["kind"]) or r["kind"] == "loo") and r["job_dir"] not in have:
            frames.append(pd.DataFrame([{
                "fold": pd.to_numeric(r.get("fold"), errors="coerce"), "condition": r.get("condition"),
                "status": "error", "error": r["error"], "success": False, "job_dir": r["job_dir"]}]))
    if not frames:
        return pd.DataFrame(columns=["fold", "condition", "status", "success"])
    return pd.concat(frames, ignore_index=True)


def sweep_tables(sw: Sweep) -> tuple[dict, str | None]:
    """The summary tables of a collected sweep (name -> DataFrame) and the name of the main one."""
    t = sw.tables
    out: dict[str, pd.DataFrame] = {}
    main = None
    keys = [_axis_column(k, ()) for k in sw.axes if _axis_column(k, ()) not in ("condition", "fold")]
    if "converse_constraints" in t or "converse_speakers" in t:
        cons = t.get("converse_constraints", pd.DataFrame())
        spk = t.get("converse_speakers", pd.DataFrame())
        out["converse_by_condition"] = summaries.converse_constraints_met(cons, spk, keys)
        out["converse_by_kind"] = summaries.converse_constraints_by_kind(cons, spk, keys)
        out["converse_speakers"] = spk
        main = "converse_by_condition"
    if "leaderboard" in t:
        out["leaderboard"] = t["leaderboard"]
        out["leaderboard_wide"] = summaries.leaderboard_wide(t["leaderboard"], keys)
        main = main or "leaderboard_wide"
    if "walktalk" in t:
        out["walktalk"] = t["walktalk"]
        main = main or "walktalk"
    for name in ("cdbn_head", "cdbn_gestures", "cdbn_hands"):
        if name in t:
            out[name] = t[name]
            main = main or ("cdbn_head" if name == "cdbn_head" else None)
    return out, main


def write_collected(cases: pd.DataFrame, out_dir: str | Path, sweep: Sweep | None = None) -> dict:
    """Write the merged tables and the summary tables (CSV + Markdown), print the main table. ``cases``:
    leave-one-out cases (may be empty); ``sweep``: the other kinds' tables. Returns a summary dict."""
    from ..utils import atomic_path, write_text_atomic

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    tables: dict[str, pd.DataFrame] = {}
    main = None
    if len(cases) or sweep is None:
        ok = cases[cases["status"] != "error"] if "status" in cases else cases
        has_char = "character" in ok and len(ok)
        tables.update({
            "all_cases": cases,
            "success_rates": summaries.success_rates(ok) if has_char else pd.DataFrame(),
            "success_by_character": summaries.success_by_character(ok) if has_char else pd.DataFrame(),
            "table3": summaries.timing_table(ok) if "synthesis_seconds" in ok else pd.DataFrame(),
            "cooccurrence_by_condition": summaries.cooccurrence_by_condition(ok) if has_char else pd.DataFrame(),
            "quality_by_condition": summaries.quality_by_condition(ok) if has_char else pd.DataFrame(),
        })
        main = "success_rates"
    if sweep is not None:
        more, more_main = sweep_tables(sweep)
        tables.update(more)
        main = main if len(cases) else more_main
        tables["jobs"] = sweep.jobs
    for name, df in tables.items():
        with atomic_path(out_dir / f"{name}.csv") as tmp:
            df.to_csv(tmp, index=False)
        if name not in ("all_cases", "jobs", "converse_speakers"):
            write_text_atomic(out_dir / f"{name}.md", summaries.to_markdown(df))
    if sweep is not None:
        n_err, n_jobs = sweep.num_failed, int(len(sweep.jobs))
    else:
        n_err = int((cases.get("status") == "error").sum()) if "status" in cases else 0
        n_jobs = None
    if main is not None:
        print(f"\n{main} ({out_dir / (main + '.md')})\n" + summaries.to_markdown(tables[main]))
    return {"num_rows": int(len(cases)), "num_jobs": n_jobs, "num_failed_jobs": n_err,
            "kinds": sweep.kinds if sweep is not None else ["loo"], "axes": sweep.axes if sweep is not None else [],
            "main_table": main, "tables": sorted(tables)}
