"""Finished runs on disk: finding the newest run of a task, and resolving the paths a run recorded.

A task writes its results and ``summary.json`` into Hydra's output folder
(``outputs/<task>/<stamp>/``, or ``multirun/<task>/<stamp>/<job>/``). Paths a run recorded may be
relative: relative to the directory ``convsynth`` ran in (Hydra's ``runtime.cwd``, kept in the run's
``.hydra/hydra.yaml``), not to the run folder nor to whoever reads it later (a notebook kernel runs in
``notebooks/``). :func:`resolve_recorded` turns such a path into the file it named.
"""
from __future__ import annotations

import json
from pathlib import Path

import yaml

from ..errors import FormatError, MissingFileError


def read_summary(run: str | Path) -> dict:
    """The ``summary.json`` of a run folder (an error naming the file when it is missing or unreadable)."""
    f = Path(run) / "summary.json"
    if not f.is_file():
        raise MissingFileError("not a finished run: no summary.json (run the task first)", f)
    try:
        return json.loads(f.read_text())
    except json.JSONDecodeError as e:
        raise FormatError(f"unreadable summary ({e})", f) from None


def launch_dir(run: str | Path) -> Path | None:
    """The directory ``convsynth`` ran in for this run: Hydra's ``runtime.cwd`` from
    ``.hydra/hydra.yaml``; None when the run folder has no Hydra record (a run started from Python)."""
    f = Path(run) / ".hydra" / "hydra.yaml"
    if not f.is_file():
        return None
    try:
        cwd = ((yaml.safe_load(f.read_text()) or {}).get("hydra") or {}).get("runtime", {}).get("cwd")
    except yaml.YAMLError:
        return None
    return Path(cwd) if cwd else None


def resolve_recorded(run: str | Path, value: str | Path) -> Path:
    """The absolute path of ``value``, a path the run in folder ``run`` recorded. Absolute paths are
    returned as they are; a relative one is tried against, in turn, the directory the run was launched
    in (:func:`launch_dir`), the directory above Hydra's ``outputs/`` or ``multirun/`` that holds the
    run, and the run folder itself; the first that exists wins. None exists: an error naming every
    place tried."""
    p = Path(value)
    if p.is_absolute():
        return p
    run = Path(run).resolve()
    bases = []
    if launch_dir(run) is not None:
        bases.append(launch_dir(run))
    for parent in run.parents:  # .../outputs/<task>/<stamp> or .../multirun/<task>/<stamp>/<job>
        if parent.name in ("outputs", "multirun"):
            bases.append(parent.parent)
            break
    bases.append(run)
    for b in bases:
        if (b / p).exists():
            return (b / p).resolve()
    raise MissingFileError(f"the run recorded the relative path {str(p)!r}, found under none of "
                           f"{', '.join(str(b) for b in bases)}", run / "summary.json")


def newest_run(base: str | Path, task: str, holding: str = "summary.json") -> Path | None:
    """The newest finished run of ``task`` under ``base`` (``base/outputs/<task>/<stamp>/`` holding
    ``holding``; stamps sort by time), or None."""
    runs = sorted(Path(base).glob(f"outputs/{task}/*/{holding}"))
    return runs[-1].parent if runs else None
