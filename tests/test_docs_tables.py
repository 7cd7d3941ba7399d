"""Tables of the README and docs/ marked with ``<!-- numbers: FILE ... -->`` quote their results files:
every number a marker ties to a value equals that value rounded to the digits the page shows
(``convsynth_jax/docs_tables.py``; the marker's syntax: docs/testing.md). A page whose file changed
fails here until ``python experiments/results_doc.py --tables`` rewrites it."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from convsynth_jax.docs_tables import (check_pages, check_text, checked_counts, format_like, marked_pages, numbers_in,
                                       parse_markers, regenerate_pages, regenerate_text, resolve, shows)
from convsynth_jax.errors import FormatError

ROOT = Path(__file__).resolve().parents[1]
# the tables whose markers must stay: (page, results file)
MARKED = {
    ("docs/flow_matching.md", "experiments/results/fm2_steps1600_17folds.json"),
    ("docs/flow_matching.md", "experiments/results/flow_matching_benchmark_6folds/leaderboard.csv"),
    ("docs/results.md", "experiments/results/naturalness.json"),
    ("docs/results.md", "experiments/results/naturalness_17folds.json"),
    ("docs/results.md", "experiments/results/naturalness_hubs_17folds.json"),
    ("docs/motion_graph.md", "experiments/results/naturalness_hubs_17folds.json"),
    ("docs/motion_graph.md", "experiments/results/naturalness_sweep_3folds.json"),
    ("docs/motion_graph.md", "experiments/results/naturalness_17folds_controls.json"),
    ("docs/cdbn.md", "experiments/results/cdbn_energy.json"),
    ("docs/converse.md", "experiments/results/bench_converse.json"),
    ("docs/performance.md", "experiments/results/bench_startup.json"),
    ("docs/scale.md", "experiments/results/bench_scale.json"),
}


@pytest.mark.parametrize("page", marked_pages(ROOT), ids=lambda p: p.name)
def test_every_marked_number_equals_its_results_file(page):
    bad = check_text(page.read_text(), str(page.relative_to(ROOT)), ROOT)
    assert not bad, "numbers that differ from their files (python experiments/results_doc.py --tables):\n" + "\n".join(bad)


def test_every_marker_checks_numbers_and_the_main_tables_are_marked():
    found = set()
    for page in marked_pages(ROOT):
        for table, n in checked_counts(page.read_text(), str(page.relative_to(ROOT)), ROOT):
            assert n > 0, f"{table.page}:{table.marker + 1}: a marker that ties no number to {table.file}"
            assert (ROOT / table.file).exists(), f"{table.page}:{table.marker + 1}: no file {table.file}"
            found.add((table.page, table.file))
    assert MARKED <= found, f"markers removed: {sorted(MARKED - found)}"


def test_an_edited_number_on_a_real_page_is_caught():
    text = (ROOT / "docs" / "flow_matching.md").read_text()
    row = next(ln for ln in text.splitlines() if ln.startswith("| `flow_matching` |"))
    first = numbers_in(row.split("|")[2])[0].group(0)             # the raw FGD the row quotes
    edited = row.replace(f"| {first} ", f"| {float(first) + 0.1:.1f} ", 1)
    assert edited != row
    bad = check_text(text.replace(row, edited), "docs/flow_matching.md", ROOT)
    assert len(bad) == 1 and "fgd_raw" in bad[0] and f"page {float(first) + 0.1:.1f}" in bad[0]


def _page(tmp_path: Path, table: str, marker: str, data) -> tuple[Path, str]:
    (tmp_path / "r.json").write_text(json.dumps(data))
    text = f"# A page\n\n{marker.strip()}\n\n{table.strip()}\n\nprose 1.5 after\n"
    return tmp_path, text


DATA = {"summary": {"a": {"fgd": 78.83, "std_f": 0.927, "still": 0.000672, "ci": [0.67, 0.76]},
                    "b.c": {"fgd": 10.84, "std_f": 0.9756, "still": 0.00291, "ci": [0.1, 0.2]}},
        "floor": 19.21, "rows": [{"who": "f", "kind": "PC-LH", "rate": 0.621}, {"who": "m", "kind": "PC-LH", "rate": 0.506}]}
MARKER = """<!-- numbers: r.json
row `a` = summary.a
row b = summary.b.c
head 2 = summary.b.c.fgd
col 2 = {row}.fgd
col std = {row}.std_f {row}.ci.0 {row}.ci.1
col 4 = {row}.still%
cell b | std = {row}.std_f
cell 3 | 2 = floor
-->"""
TABLE = """| system | FGD (b 10.8) | std | still |
|---|---|---|---|
| `a` | 78.8 (7.3x) | 0.93 [0.67, 0.76] | 0.07% |
| b | 10.8 | 0.98 | 0.29% |
| floor | 19.2 | | |"""


def test_the_rule_catches_each_edited_number_and_regenerates_the_page(tmp_path):
    root, text = _page(tmp_path, TABLE, MARKER.replace("{row}.fgd\n", "{row}.fgd -\n").replace(
        "cell 3 | 2 = floor", "cell b | 2 = {row}.fgd\ncell 3 | 2 = floor"), DATA)
    assert check_text(text, "p.md", root) == []
    assert sum(n for _, n in checked_counts(text, "p.md", root)) == 10   # every number but the 7.3x
    for old, new in [("78.8 (", "78.9 ("), ("0.93 [", "0.92 ["), ("0.76]", "0.77]"), ("0.07%", "0.08%"),
                     ("| 10.8 |", "| 10.9 |"), ("(b 10.8)", "(b 10.7)"), ("19.2", "19.3"), ("0.29%", "0.28%")]:
        edited = text.replace(old, new, 1)
        assert edited != text
        bad = check_text(edited, "p.md", root)
        assert len(bad) == 1, (old, bad)
        fixed, changes = regenerate_text(edited, "p.md", root)
        assert len(changes) == 1 and fixed == text, (old, changes)
        assert check_text(fixed, "p.md", root) == []


def test_a_marker_that_does_not_fit_its_table_is_reported(tmp_path):
    root, text = _page(tmp_path, TABLE, MARKER, DATA)
    # row b's FGD cell has one number, col 2 names one spec: fits; the `a` row's has two
    bad = check_text(text, "p.md", root)
    assert len(bad) == 1 and "2 numbers on the page (78.8, 7.3), 1 specs" in bad[0]
    for marker, says in [(MARKER.replace("summary.a\n", "summary.zz\n"), "no key 'zz'"),
                         (MARKER.replace("row b =", "row c ="), "no row 'c'"),
                         (MARKER.replace("col 4 =", "col 9 ="), "no column '9'")]:
        _, text = _page(tmp_path, TABLE, marker, DATA)
        assert any(says in b for b in check_text(text, "p.md", root)), says
    with pytest.raises(FormatError, match="p.md:3: numbers marker not followed by a Markdown table"):
        parse_markers(f"# A page\n\n{MARKER}\n\nprose\n", "p.md")
    with pytest.raises(FormatError, match="p.md:5: expected 'row"):
        parse_markers("# A page\n\n<!-- numbers: r.json\nrow a = x\nrows b\n-->\n" + TABLE, "p.md")


def test_records_csv_head_and_multi_word_rows(tmp_path):
    root, text = _page(tmp_path, "| who | PC-LH |\n|---|---|\n| f | 62.1 |\n| m | 50.6 |", """
<!-- numbers: r.json
row f = rows.who=f&kind={head}.rate%
row m = rows.who=m&kind={head}.rate%
col 2 = {row}
-->""", DATA)
    assert check_text(text, "p.md", root) == [] and check_text(text.replace("50.6", "50.7"), "p.md", root) != []
    (root / "t.csv").write_text("system,metric,value\nx,jerk,21550.36\nx,fgd,0.5\n")
    _, text = _page(tmp_path, "| measure | x |\n|---|---|\n| both | 2.16e4, 21.6k, 0.50 |", """
<!-- numbers: t.csv
row both = jerk jerk fgd
col x = system=x&metric={row}.value
-->""", DATA)
    assert check_text(text, "p.md", root) == []
    assert len(check_text(text.replace("21.6k", "21.5k"), "p.md", root)) == 1
    assert resolve({"a.b": {"c": [1, {"d": 2}]}}, "a.b.c.1.d") == 2


def test_numbers_in_a_cell_skip_words_ranges_and_identifiers():
    cell = "v5 PC-LH/RH 29/58 0.65 [0.67, 0.76], folds 0-9, 7.3x, 0.33%, 1,247 of -0.233 e1848f1 2.15e+04 21.5k"
    assert [m.group(0) for m in numbers_in(cell)] == ["29", "58", "0.65", "0.67", "0.76", "0", "7.3", "0.33", "1,247",
                                                      "-0.233", "2.15e+04", "21.5k"]


def test_format_like_writes_what_shows_reads():
    rng = np.random.default_rng(0)
    for text in ("0.16", "164", "21.5k", "2.15e+04", "2.16e4", "1,247", "0", "0.0003", "-0.233"):
        for value in rng.uniform(-3, 3, 50) * 10.0 ** rng.integers(-4, 5, 50):
            out = format_like(text, value)
            assert shows(out, value), (text, value, out)
            assert ("k" in out) == ("k" in text) and ("e" in out) == ("e" in text)
    assert format_like("0.16", 0.1234) == "0.12" and format_like("21.5k", 21459) == "21.5k"
    assert format_like("1,247", 1300.2) == "1,300" and format_like("2.15e+04", 21560) == "2.16e+04"


def test_a_marker_in_a_code_block_is_an_example():
    fenced = f"# A page\n\n```markdown\n{MARKER}\n| a | b |\n```\n"
    assert parse_markers(fenced, "p.md") == []
    with pytest.raises(FormatError, match="not followed by a Markdown table"):
        parse_markers(fenced.replace("```markdown\n", "").replace("```\n", ""), "p.md")


def test_regenerate_pages_rewrites_the_pages_whose_numbers_differ(tmp_path):
    marker = MARKER.replace("{row}.fgd\n", "{row}.fgd -\n").replace("cell 3 | 2 = floor", "cell b | 2 = {row}.fgd\ncell 3 | 2 = floor")
    root, text = _page(tmp_path, TABLE, marker, DATA)
    (root / "docs").mkdir()
    (root / "docs" / "good.md").write_text(text)
    (root / "docs" / "stale.md").write_text(text.replace("0.07%", "0.09%"))
    (root / "docs" / "plain.md").write_text("# no marker\n\n| a |\n|---|\n| 1.5 |\n")
    assert [p.name for p in marked_pages(root)] == ["good.md", "stale.md"]
    assert len(check_pages(root)) == 1
    changes = regenerate_pages(root)
    assert len(changes) == 1 and "0.09 -> 0.07" in changes[0]
    assert (root / "docs" / "stale.md").read_text() == text and check_pages(root) == []
