"""Numbers quoted in the docs equal their results files: each table below is read from its page and
every cell compared with the row of the results file it quotes. A quoted number must equal the file's
value rounded to the digits the page shows (``0.16`` quotes 0.159, ``21.5k`` quotes 21459, ``2.15e+04``
quotes 21459, ``0`` quotes 2.7e-11); a rank ``(n)`` and an interval ``[low, high]`` likewise. A table
whose file changed (a new sweep, a new scoring) fails here until the page is updated. The rule
(:func:`convsynth_jax.docs_tables.shows`) is the one every marked table of the docs is checked by
(``tests/test_docs_tables.py``)."""
from __future__ import annotations

import re
from pathlib import Path

import pandas as pd
import pytest

from convsynth_jax.docs_tables import shows

ROOT = Path(__file__).resolve().parents[1]
LEADERBOARD = ROOT / "experiments" / "results" / "bench_metrics_leaderboard.csv"


def _table(page: Path, header_start: str) -> list[dict]:
    """The Markdown table of ``page`` whose header row starts with ``header_start``: rows as dicts."""
    lines = page.read_text().splitlines()
    start = next(i for i, ln in enumerate(lines) if ln.startswith(header_start))
    cols = [c.strip() for c in lines[start].strip("|").split("|")]
    rows = []
    for ln in lines[start + 2:]:
        if not ln.startswith("|"):
            break
        rows.append(dict(zip(cols, (c.strip() for c in ln.strip("|").split("|")))))
    return rows


def _mismatches(rows: list[dict], scope: str, systems: dict, metrics: dict, board: pd.DataFrame) -> list[str]:
    bad = []
    first = next(iter(rows[0]))
    for row in rows:
        system = systems.get(row[first], row[first])
        for col, metric in metrics.items():
            cell = row[col]
            if cell in ("–", "-", ""):
                continue
            hit = board[(board.system == system) & (board.scope == scope) & (board.metric == metric)]
            if len(hit) != 1:
                bad.append(f"{system}/{scope}/{metric}: not in {LEADERBOARD.name}")
                continue
            r = hit.iloc[0]
            if not shows(cell, r["value"]):
                bad.append(f"{system}/{scope}/{metric}: page {cell!r}, file {r['value']:.6g}")
            rank = re.search(r"\((\d+)\)", cell)
            if rank and int(rank.group(1)) != int(r["rank"]):
                bad.append(f"{system}/{scope}/{metric}: page rank {rank.group(1)}, file {int(r['rank'])}")
            interval = re.search(r"\[([^,\]]+), ([^\]]+)\]", cell)
            if interval and not (shows(interval.group(1), r["ci_low"]) and shows(interval.group(2), r["ci_high"])):
                bad.append(f"{system}/{scope}/{metric}: page interval {interval.group(0)}, file "
                           f"[{r['ci_low']:.4g}, {r['ci_high']:.4g}]")
        solved = re.search(r"(\d+) windows solved", row[first])
        if solved:
            n = int(board[(board.system == system) & (board.scope == scope)]["n_windows"].iloc[0])
            if int(solved.group(1)) != n:
                bad.append(f"{system}: page {solved.group(1)} windows solved, file {n}")
    return bad


@pytest.mark.parametrize("scope", ["body", "head"])
def test_metrics_page_leaderboard_equals_its_results_file(scope):
    board = pd.read_csv(LEADERBOARD)
    rows = _table(ROOT / "docs" / "metrics.md", f"| {scope} | fgd_raw")
    metrics = {c: c for c in rows[0] if c != scope}
    assert _mismatches(rows, scope, {}, metrics, board) == []


def test_readme_leaderboard_equals_its_results_file():
    board = pd.read_csv(LEADERBOARD)
    rows = _table(ROOT / "README.md", "| system | FGD raw")
    systems = {"ground truth": "ground_truth", "mismatched ground truth": "mismatched_ground_truth",
               "random playback": "random_playback"}
    systems.update({r["system"]: "motion_graph" for r in rows if r["system"].startswith("motion graph")})
    metrics = {"FGD raw": "fgd_raw", "FGD AE-60": "fgd_ae60", "beat consistency": "beat_consistency",
               "jerk (cm/s³)": "jerk", "GAC": "gac", "CCA_m": "cca_m"}
    assert set(metrics) == set(rows[0]) - {"system"}, "a column of the README's leaderboard is not checked"
    assert _mismatches(rows, "body", systems, metrics, board) == []


def test_the_rule_catches_a_changed_number():
    assert shows("0.16", 0.159) and shows("21.5k", 21459.4) and shows("2.15e+04", 21459.4) and shows("0", 2.7e-11)
    assert shows("0.0003", 0.000259) and shows("164", 163.66)
    assert not shows("0.17", 0.159) and not shows("21.4k", 21459.4) and not shows("165", 163.66)
    board = pd.DataFrame([{"system": "a", "scope": "body", "metric": "m", "value": 0.5, "ci_low": 0.4,
                           "ci_high": 0.6, "n_windows": 10, "rank": 2.0}])
    ok = [{"body": "a", "m": "0.5 (2) [0.4, 0.6]"}]
    assert _mismatches(ok, "body", {}, {"m": "m"}, board) == []
    for cell in ("0.6 (2) [0.4, 0.6]", "0.5 (1) [0.4, 0.6]", "0.5 (2) [0.3, 0.6]"):
        assert len(_mismatches([{"body": "a", "m": cell}], "body", {}, {"m": "m"}, board)) == 1
