"""Provenance of a result: the command, its overrides, the commit, the date and the machine's load.

Every benchmark and analysis under ``experiments/`` writes its figures with :func:`write_result` or
:func:`write_result_markdown`, which put ``<name>.manifest.json`` beside them, so a number in ``docs/``
can be traced to the run that made it; :func:`results_inventory` lists every stored result with its
manifest (``experiments/results_doc.py`` writes that list to ``docs/results_inventory.md``)."""
from __future__ import annotations

import json
import os
import resource
import platform
import shlex
import subprocess
import sys
import time
from datetime import datetime, timezone
from pathlib import Path
from typing import Callable, Mapping, NamedTuple

from .utils import write_text_atomic

REPO = Path(__file__).resolve().parent.parent
RESULTS = REPO / "experiments" / "results"     # the stored results of a checkout
# real recordings: $CONVSYNTH_SHARED/data (as the tests read it), else the shared folder beside a checkout
SHARED_DATA = Path(os.environ.get("CONVSYNTH_SHARED", REPO.parent / "shared")) / "data"


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


def peak_rss_mb() -> float:
    """This process's peak resident memory so far, in MiB (Linux reports KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def process_memory_mb(field: str) -> float:
    """A ``VmXXX`` field of /proc/self/status (``VmRSS``: resident now, ``VmHWM``: its peak) in MiB;
    NaN where the file is not there (not Linux)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith(field + ":"):
                return float(line.split()[1]) / 1024.0
    except OSError:
        pass
    return float("nan")


def reset_peak_rss() -> bool:
    """Reset this process's peak resident memory (``VmHWM``) so that it measures what follows
    (Linux >= 4.0); False where that is not possible."""
    try:
        Path("/proc/self/clear_refs").write_text("5")
        return True
    except OSError:
        return False


def timed(fn: Callable, *args, **kwargs):
    """(fn(*args, **kwargs), wall seconds)."""
    t = time.perf_counter()
    out = fn(*args, **kwargs)
    return out, time.perf_counter() - t


class ProcessRun(NamedTuple):
    """A finished ``convsynth`` process: exit status, wall and CPU seconds (the child's user + system),
    the 1-minute load average before and after, and its output."""

    returncode: int
    wall_s: float
    cpu_s: float
    load_avg_1min: list
    stdout: str
    stderr: str

    def check(self) -> "ProcessRun":
        """This run, or SystemExit with the tail of its output when it failed."""
        if self.returncode != 0:
            raise SystemExit(f"convsynth exited with {self.returncode}:\n{self.stdout[-3000:]}\n{self.stderr[-3000:]}")
        return self


def run_convsynth(overrides, out_dir: Path | None = None, cache: Path | None = None) -> ProcessRun:
    """``python -m convsynth_jax.config *overrides`` in a fresh process from the repository (what a user's
    ``convsynth`` runs), with ``hydra.run.dir=out_dir`` and ``CONVSYNTH_CACHE=cache`` when given, timed
    by the wall clock and by the child's CPU time: the start-up a user sees is part of the figure."""
    env = dict(os.environ, **({"CONVSYNTH_CACHE": str(cache)} if cache is not None else {}))
    env["PYTHONPATH"] = os.pathsep.join(x for x in (str(REPO), env.get("PYTHONPATH")) if x)
    cmd = [sys.executable, "-m", "convsynth_jax.config", *map(str, overrides),
           *([f"hydra.run.dir={out_dir}"] if out_dir is not None else [])]
    load = os.getloadavg()[0]
    ru0, t = resource.getrusage(resource.RUSAGE_CHILDREN), time.perf_counter()
    r = subprocess.run(cmd, env=env, capture_output=True, text=True, cwd=str(REPO))
    wall, ru1 = time.perf_counter() - t, resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (ru1.ru_utime - ru0.ru_utime) + (ru1.ru_stime - ru0.ru_stime)
    return ProcessRun(r.returncode, wall, cpu, [load, os.getloadavg()[0]], r.stdout, r.stderr)


def write_result_manifest(name: str, overrides=None, folder: Path | None = None, **extra) -> Path:
    """``<folder>/<name>.manifest.json``, or ``<folder>/<name>/manifest.json`` when ``<name>`` is a folder
    (``folder``: :data:`RESULTS` unless given)."""
    folder = Path(folder or RESULTS)
    folder.mkdir(parents=True, exist_ok=True)
    target = folder / name
    path = target / "manifest.json" if target.is_dir() else folder / f"{name}.manifest.json"
    return write_text_atomic(path, json.dumps(run_manifest(overrides=overrides, **extra), indent=2) + "\n")


def write_result(name: str, result: Mapping, overrides=None, folder: Path | None = None) -> Path:
    """``<folder>/<name>.json`` (numbers that JSON lacks written as floats) and its manifest."""
    folder = Path(folder or RESULTS)
    folder.mkdir(parents=True, exist_ok=True)
    path = write_text_atomic(folder / f"{name}.json", json.dumps(result, indent=2, default=float))
    write_result_manifest(name, overrides=overrides, folder=folder)
    return path


def write_result_markdown(name: str, lines: list, overrides=None, folder: Path | None = None) -> Path:
    """``<folder>/<name>.md`` from the lines of a Markdown table, and its manifest."""
    folder = Path(folder or RESULTS)
    folder.mkdir(parents=True, exist_ok=True)
    path = write_text_atomic(folder / f"{name}.md", "\n".join(lines) + "\n")
    write_result_manifest(name, overrides=overrides, folder=folder)
    return path


# ---------------------------------------------------------------------------------------------------
# The inventory of stored results

_SCRIPT_DIRS = ("bench", "analysis", "paper")


def _scripts(experiments: Path, retired: Mapping[str, str]) -> dict[str, str]:
    """Script stem -> path relative to experiments/ (present or retired), longest stems first."""
    found = {Path(rel).stem: rel for rel in retired}
    for d in _SCRIPT_DIRS:
        for p in sorted((experiments / d).glob("*.py")):
            if not p.stem.startswith("_"):
                found[p.stem] = f"{d}/{p.name}"
    return dict(sorted(found.items(), key=lambda kv: -len(kv[0])))


def _script_cell(script: str, retired: Mapping[str, str]) -> str:
    """A present script as its path; a retired one by name with the commit that still holds it (a path
    that no longer exists is not written, so the inventory names no missing file)."""
    if script in retired:
        return f"`{Path(script).name}` (retired; in git at {retired[script]})"
    return f"`experiments/{script}`"


def describe_result(rel: Path, scripts: Mapping[str, str], writers: Mapping[str, str] = (),
                    suffixes: Mapping[str, str] = (), retired: Mapping[str, str] = ()) -> str:
    """What a stored result is, from its path relative to the results folder ('' when the name does not
    say): the script whose name starts the file's (``writers``: result prefix -> script, for the others)
    and what the rest of the name says (``suffixes`` spells out the short ones)."""
    writers, suffixes, retired = dict(writers), dict(suffixes), dict(retired)
    if len(rel.parts) > 1 and rel.name == "bench_loo.json":
        return f"leave-one-out sweep (`experiments/bench/bench_loo.py`), run `{rel.parts[0].removeprefix('loo_')}`"

    def variant(rest: str) -> str:
        rest = rest.strip("_")
        return f", {suffixes.get(rest, rest.replace('_', ' '))}" if rest else ""

    for prefix, script in [*writers.items(), *scripts.items()]:
        if rel.stem == prefix or rel.stem.startswith(prefix + ("" if prefix in writers else "_")):
            return _script_cell(script, retired) + variant(rel.stem[len(prefix):])
    return ""


def _git_stored(path: Path) -> tuple[str, str]:
    out = _git("log", "-1", "--format=%h %ad", "--date=short", "--", str(path.relative_to(REPO)))
    parts = (out or "").split()
    return (f"stored {parts[0]}", parts[1]) if len(parts) == 2 else ("-", "-")


def _command_cell(command: str, retired: Mapping[str, str]) -> str:
    for script, commit in retired.items():
        command = command.replace(f"experiments/{script}", f"{Path(script).name} (retired; in git at {commit})")
    return f"`{command}`"


def results_inventory(results: Path | None = None, writers: Mapping[str, str] = (), suffixes: Mapping[str, str] = (),
                      retired: Mapping[str, str] = ()) -> list[tuple[str, str, str, str, str]]:
    """(link, what it is, command, commit, date) of every ``results/**/*.json`` that is not a manifest.

    Command, commit and date come from the result's manifest (``<name>.manifest.json`` beside it, or
    ``manifest.json`` of its folder). Without one the command is ``manifest: none`` (plus any command
    recorded inside the file) and the commit and date are those of the git commit that last stored the
    file (``stored ...``). ``retired``: script path relative to experiments/ -> the commit that last
    held it, for results whose script was retired."""
    results = Path(results or RESULTS)
    retired = dict(retired)
    scripts = _scripts(results.parent, retired)
    out = []
    for path in sorted(results.rglob("*.json")):
        if path.name == "manifest.json" or path.name.endswith(".manifest.json"):
            continue
        rel = path.relative_to(results)
        beside = path.with_name(path.stem + ".manifest.json")
        folder = path.parent / "manifest.json"
        man_path = beside if beside.exists() else folder if path.parent != results and folder.exists() else None
        if man_path is not None:
            man = json.loads(man_path.read_text())
            command = _command_cell(str(man.get("command", "?")), retired)
            if man.get("overrides"):
                command += " (overrides: " + " ".join(f"`{o}`" for o in man["overrides"]) + ")"
            commit = (man.get("commit") or "?")[:7] + (" (dirty)" if man.get("dirty") else "")
            date = (man.get("date") or "?")[:10]
        else:
            try:
                data = json.loads(path.read_text())
            except json.JSONDecodeError:
                data = None
            inner = data.get("command") if isinstance(data, dict) else None
            command = "manifest: none" + (f"; in the file: {_command_cell(inner, retired)}" if isinstance(inner, str) else "")
            commit, date = _git_stored(path)
        link = f"[{rel.as_posix()}](../experiments/results/{rel.as_posix()})"
        out.append((link, describe_result(rel, scripts, writers, suffixes, retired), command, commit, date))
    return out
