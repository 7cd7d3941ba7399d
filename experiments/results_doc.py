"""An inventory of the stored results: one Markdown row per ``experiments/results/**/*.json``.

For each result it prints what it is (when the file name says so), the command that made it, the
commit and the date. These come from the result's manifest, ``<name>.manifest.json`` beside it or
``<folder>/manifest.json`` for a folder (written by ``experiments/bench/_bench.py``). A result
without a manifest shows ``manifest: none``; the command recorded inside the file, if any, is then
shown instead, and the commit and date are those of the git commit that last stored the file
(marked ``stored``), which is not necessarily the commit that computed it.

    python experiments/results_doc.py                              # print the table
    python experiments/results_doc.py --out docs/results_inventory.md

Standard library only.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
RESULTS = REPO / "experiments" / "results"
SCRIPT_DIRS = ("bench", "analysis", "paper")
# Results whose name does not start with the name of the script that writes them.
WRITERS = {"loo_seams_summary": "analysis/seam_summary.py", "cdbn_energy_benchmark": "analysis/cdbn_benchmark_summary.py"}
SUFFIXES = {
    "h100": "on one H100 GPU",
    "m4096": "with search.max_candidates=4096",
    "quick": "quick mode (--quick)",
    "fig6": "Fig. 6 random-initialization study (--fig6)",
    "hands": "hand model (--hands)",
    "combined": "every goal at once (--combined)",
    "jerk": "jerk against splice.rescale_coupling (--jerk-coupling)",
    "loop_seams": "loop seam correction (--loop-seams)",
}


def _scripts() -> dict[str, str]:
    """Script stem -> path relative to experiments/, longest stems first."""
    found = {}
    for d in SCRIPT_DIRS:
        for p in sorted((REPO / "experiments" / d).glob("*.py")):
            if not p.stem.startswith("_"):
                found[p.stem] = f"{d}/{p.name}"
    return dict(sorted(found.items(), key=lambda kv: -len(kv[0])))


def describe(rel: Path, scripts: dict[str, str]) -> str:
    """What a result is, from its path alone ('' when the name does not say)."""
    if len(rel.parts) > 1 and rel.name == "bench_loo.json":
        variant = rel.parts[0].removeprefix("loo_")
        return f"leave-one-out sweep (`experiments/bench/bench_loo.py`), run `{variant}`"
    stem = rel.stem
    for prefix, script in WRITERS.items():
        if stem.startswith(prefix):
            return f"`experiments/{script}`" + _variant(stem[len(prefix):])
    for name, script in scripts.items():
        if stem == name or stem.startswith(name + "_"):
            return f"`experiments/{script}`" + _variant(stem[len(name):])
    return ""


def _variant(rest: str) -> str:
    rest = rest.strip("_")
    if not rest:
        return ""
    return f", {SUFFIXES.get(rest, rest.replace('_', ' '))}"


def manifest_for(path: Path) -> Path | None:
    beside = path.with_name(path.stem + ".manifest.json")
    if beside.exists():
        return beside
    if path.parent != RESULTS and (path.parent / "manifest.json").exists():
        return path.parent / "manifest.json"
    return None


def _git_stored(path: Path) -> tuple[str, str]:
    try:
        r = subprocess.run(["git", "log", "-1", "--format=%h %ad", "--date=short", "--",
                            str(path.relative_to(REPO))], cwd=REPO, capture_output=True,
                           text=True, timeout=20)
    except (OSError, subprocess.SubprocessError):
        return "-", "-"
    parts = r.stdout.split()
    return (f"stored {parts[0]}", parts[1]) if r.returncode == 0 and len(parts) == 2 else ("-", "-")


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def rows() -> list[tuple[str, str, str, str, str]]:
    scripts = _scripts()
    out = []
    for path in sorted(RESULTS.rglob("*.json")):
        if path.name == "manifest.json" or path.name.endswith(".manifest.json"):
            continue
        rel = path.relative_to(RESULTS)
        man_path = manifest_for(path)
        if man_path is not None:
            man = json.loads(man_path.read_text())
            command = f"`{man.get('command', '?')}`"
            overrides = man.get("overrides") or []
            if overrides:
                command += " (overrides: " + " ".join(f"`{o}`" for o in overrides) + ")"
            commit = (man.get("commit") or "?")[:7] + (" (dirty)" if man.get("dirty") else "")
            date = (man.get("date") or "?")[:10]
        else:
            try:
                data = json.loads(path.read_text())
            except json.JSONDecodeError:
                data = None
            inner = data.get("command") if isinstance(data, dict) else None
            command = "manifest: none"
            if isinstance(inner, str):
                command += f"; in the file: `{inner}`"
            commit, date = _git_stored(path)
        link = f"[{rel.as_posix()}](../experiments/results/{rel.as_posix()})"
        out.append((link, describe(rel, scripts), command, commit, date))
    return out


def markdown() -> str:
    lines = [
        "# Stored results",
        "",
        "Generated by `python experiments/results_doc.py --out docs/results_inventory.md` from "
        "`experiments/results/**/*.json` and their manifests; do not edit by hand. "
        "`manifest: none`: the result predates manifests; its commit and date are then those of "
        "the git commit that stored the file (`stored`), not necessarily the code that computed it. "
        "What the figures mean: [results.md](results.md).",
        "",
        "| result | what it is | command | commit | date |",
        "|---|---|---|---|---|",
    ]
    for r in rows():
        lines.append("| " + " | ".join(_cell(c) for c in r) + " |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, help="write the table to this file instead of printing it")
    args = ap.parse_args(argv)
    text = markdown()
    if args.out is None:
        sys.stdout.write(text)
        return 0
    out = args.out if args.out.is_absolute() else Path.cwd() / args.out
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, out)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
