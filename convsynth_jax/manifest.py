"""Provenance of a result: the command, its overrides, the commit, the date and the machine's load.

Every benchmark and analysis under ``experiments/`` writes one beside its figures, so a number in
``docs/`` can be traced to the run that made it (``experiments/bench/_bench.py`` calls this)."""
from __future__ import annotations

import os
import platform
import shlex
import subprocess
import sys
from datetime import datetime, timezone
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


def _git(*args: str) -> str | None:
    try:
        r = subprocess.run(["git", *args], cwd=REPO, capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return None
    return r.stdout.strip() if r.returncode == 0 else None


def run_manifest(argv: list[str] | None = None, overrides: list[str] | None = None, **extra) -> dict:
    """A JSON-ready record of how a result was made.

    ``argv`` defaults to this process's command line; ``overrides`` are the Hydra overrides the run
    used (for scripts that compose a config); ``extra`` is kept as given (e.g. the corpus used)."""
    argv = list(sys.argv if argv is None else argv)
    status = _git("status", "--porcelain", "--untracked-files=no")
    try:
        load = list(os.getloadavg())
    except OSError:  # pragma: no cover - not on every platform
        load = None
    return {
        "command": " ".join(shlex.quote(a) for a in ["python", *argv]),
        "overrides": list(overrides or []),
        "commit": _git("rev-parse", "HEAD"),
        "dirty": bool(status) if status is not None else None,
        "date": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "load_avg_1_5_15": load,
        "machine": {"cpus": os.cpu_count(), "processor": platform.processor() or platform.machine(),
                    "python": platform.python_version()},
        **extra,
    }
