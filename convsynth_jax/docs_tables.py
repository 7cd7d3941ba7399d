"""Numbers in the docs that come from results files: a marker ties a Markdown table to its file.

A marker is an HTML comment (invisible on the rendered page) right above a table (blank lines may
separate them; one inside a fenced code block is an example, not a marker). Its first line names the
results file, relative to the repository; each further line maps the numbers of a row, a column or a
cell to values in the file::

    <!-- numbers: experiments/results/naturalness_17folds.json
    row `quality` = summary.quality
    row 4 = summary.random_playback
    col 3 = {row}.fgd_raw {row}.fgd_raw_random_playback_same_windows
    col still frames = {row}.still%
    cell 4 | 3 = {row}.fgd_raw
    head 3 = summary.random_playback.fgd_raw
    -->

* ``row R = KEY``: ``{row}`` stands for ``KEY`` in that row's specs. ``R`` is the row's first cell
  exactly as written, or its number (1 = the first row under the header). A key of several words
  makes one spec per word (a table with measures as rows: ``row 2 = pose_std_f pose_std_m`` with
  ``col 3 = summary.paper.{row}``); ``{head}`` in a spec stands for the column's header.
* ``col C = SPEC ...``: the specs of column ``C`` (its header exactly as written, or its number,
  1 = the first column) in every row that has a ``row`` line.
* ``cell R | C = SPEC ...``: the specs of one cell, replacing the column's for that row.
* ``head C = SPEC ...``: the specs of the numbers in column ``C``'s header.

A cell's numbers are read left to right (:func:`numbers_in`: ``78.8``, ``7.3x``, ``0.33%``, ``21.5k``,
``2.15e+04``, ``1,247``, ``-0.233``, both of ``29/58``; not the digits inside a word such as ``v5`` or ``PC-LH``) and
matched one to one with the specs; a cell whose count differs is a mismatch. A spec is

* a path into the file: keys separated by ``.`` (a key may itself contain dots: the longest key that
  matches is taken), a list index (``gt_ci.0``), or ``field=value`` (several joined by ``&``) picking
  the one record of a list whose fields have those values (a CSV file reads as such a list:
  ``system=ground_truth&scope=body&metric=fgd_raw.value``);
* prefixed by ``FILE:`` to read another file than the marker's (``experiments/results/naturalness_17folds_options.json:summary.paper``);
* suffixed by ``%`` to compare a fraction with a percentage (the value times 100);
* ``-`` for a number that is not from the file (a goal, a count in prose, a derived ratio): skipped.

A quoted number equals its value when it is the value rounded to the digits the page shows
(:func:`shows`); :func:`check_text` lists every number that is not, :func:`regenerate_text` rewrites
each such number with the file's value at the page's digits. ``experiments/results_doc.py --tables``
runs both over the README and docs/; ``tests/test_docs_tables.py`` fails on any mismatch."""
from __future__ import annotations

import csv
import json
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from .errors import FormatError
from .utils import write_text_atomic

REPO = Path(__file__).resolve().parent.parent

_NUMBER = re.compile(r"^\s*(?P<num>-?(?:\d{1,3}(?:,\d{3})+|\d+)(?:\.\d+)?(?:e[+-]?\d+)?)(?P<k>k)?")
# a number in running text: not inside a word (v5, PC-LH, e1848f1) nor the tail of a range (0-9); both
# numbers of a fraction (29/58)
_IN_CELL = re.compile(r"(?<![\w.\-])-?(?:\d{1,3}(?:,\d{3})+|\d+)(?:\.\d+)?(?:e[+-]?\d+)?k?(?![A-Za-wyz0-9_])")
_MARKER = re.compile(r"^<!-- numbers: (?P<file>\S+)\s*$")
_LINE = re.compile(r"^(?P<kind>row|col|cell|head) (?P<key>.+?) =(?: (?P<value>.*))?$")


def shows(text: str, value: float) -> bool:
    """Whether ``text`` (a number as a page prints it: ``0.16``, ``2.15e+04``, ``21.5k``, ``164``,
    ``1,247``) is ``value`` rounded to the digits ``text`` shows."""
    m = _NUMBER.match(text)
    if m is None:
        raise ValueError(f"not a number: {text!r}")
    num = m.group("num").replace(",", "")
    scale = 1000.0 if m.group("k") else 1.0
    mantissa, _, exp = num.partition("e")
    scale *= 10.0 ** int(exp) if exp else 1.0
    decimals = len(mantissa.partition(".")[2])
    return round(float(value) / scale, decimals) == round(float(mantissa), decimals)


def format_like(text: str, value: float) -> str:
    """``value`` written as ``text`` writes its number: the same digits after the point, the same
    ``k`` suffix, exponent or thousands separators (``format_like("0.16", 0.1234) == "0.12"``)."""
    m = _NUMBER.match(text)
    if m is None:
        raise ValueError(f"not a number: {text!r}")
    num = m.group("num")
    mantissa, e, exp = num.partition("e")
    decimals = len(mantissa.partition(".")[2])
    if m.group("k"):
        return f"{value / 1000.0:.{decimals}f}k"
    if e:
        return f"{value / 10.0 ** int(exp):.{decimals}f}e{exp}"
    return f"{value:{',' if ',' in num else ''}.{decimals}f}"


def numbers_in(text: str) -> list[re.Match]:
    """The numbers of a cell, left to right (matches of the number without a ``x`` or ``%`` after it)."""
    return list(_IN_CELL.finditer(text))


@dataclass
class MarkedTable:
    """A marked table of a page: the results file, its row keys and specs, and where it is.
    ``first``: the line index of the header row; ``marker``: the line index of the marker."""

    page: str
    marker: int
    first: int
    file: str
    rows: dict[str, str] = field(default_factory=dict)
    cols: dict[str, list[str]] = field(default_factory=dict)
    cells: dict[tuple[str, str], list[str]] = field(default_factory=dict)
    heads: dict[str, list[str]] = field(default_factory=dict)


def _split_row(line: str) -> list[str]:
    return [c.strip() for c in re.split(r"(?<!\\)\|", line.strip().strip("|"))]


def _cell_spans(line: str) -> list[tuple[int, int]]:
    """(start, end) of each cell's text in a table line (``| a | b |``), the pipes excluded."""
    bars = [m.start() for m in re.finditer(r"(?<!\\)\|", line)]
    if line.rstrip() and not line.rstrip().endswith("|"):
        bars.append(len(line))
    return list(zip([b + 1 for b in bars], bars[1:]))


def parse_markers(text: str, page: str = "<page>") -> list[MarkedTable]:
    """Every marked table of a Markdown text; a malformed marker raises :class:`FormatError` naming the
    page and line."""
    lines = text.splitlines()
    out = []
    i, fenced = 0, False
    while i < len(lines):
        fenced ^= lines[i].lstrip().startswith("```")
        m = None if fenced else _MARKER.match(lines[i])
        if m is None:
            i += 1
            continue
        table = MarkedTable(page, i, -1, m.group("file"))
        j = i + 1
        while j < len(lines) and lines[j].strip() != "-->":
            spec = lines[j].strip()
            lm = _LINE.match(spec)
            if spec and lm is None:
                raise FormatError(f"{page}:{j + 1}: expected 'row|col|cell|head KEY = ...' in a numbers marker, got {spec!r}")
            if spec:
                kind, key, value = lm.group("kind"), lm.group("key").strip(), (lm.group("value") or "").split()
                if kind == "row":
                    table.rows[key] = " ".join(value)
                elif kind == "col":
                    table.cols[key] = value
                elif kind == "head":
                    table.heads[key] = value
                else:
                    row, bar, col = key.rpartition(" | ")
                    if not bar:
                        raise FormatError(f"{page}:{j + 1}: a cell is 'cell ROW | COLUMN = ...', got {spec!r}")
                    table.cells[(row.strip(), col.strip())] = value
            j += 1
        if j == len(lines):
            raise FormatError(f"{page}:{i + 1}: numbers marker not closed by a line '-->'")
        k = j + 1
        while k < len(lines) and not lines[k].strip():
            k += 1
        if k + 1 >= len(lines) or not lines[k].startswith("|") or not re.match(r"^\|[\s:|-]+\|?\s*$", lines[k + 1]):
            raise FormatError(f"{page}:{i + 1}: numbers marker not followed by a Markdown table")
        table.first = k
        out.append(table)
        i = k
    return out


def _load(path: Path) -> Any:
    if not path.exists():
        raise FileNotFoundError(path)
    if path.suffix == ".csv":
        with path.open(newline="") as f:
            return list(csv.DictReader(f))
    return json.loads(path.read_text())


def resolve(data: Any, path: str) -> Any:
    """The value at ``path`` in ``data`` (keys by ``.``, the longest key that matches; list indices;
    ``field=value&...`` record filters); KeyError naming the part not found."""
    rest = path
    while rest:
        if isinstance(data, dict):
            parts = rest.split(".")
            for n in range(len(parts), 0, -1):
                if ".".join(parts[:n]) in data:
                    data, rest = data[".".join(parts[:n])], ".".join(parts[n:])
                    break
            else:
                raise KeyError(f"no key {parts[0]!r} (at {rest!r}); keys: {sorted(data)[:12]}")
        elif isinstance(data, list):
            head, _, rest = rest.partition(".")
            if "=" in head:
                want = dict(kv.split("=", 1) for kv in head.split("&"))
                hits = [r for r in data if isinstance(r, dict) and all(str(r.get(k)) == v for k, v in want.items())]
                if len(hits) != 1:
                    raise KeyError(f"{len(hits)} records match {head!r}, expected one")
                data = hits[0]
            else:
                try:
                    data = data[int(head)]
                except (ValueError, IndexError):
                    raise KeyError(f"no item {head!r} in a list of {len(data)}") from None
        else:
            raise KeyError(f"{rest!r} goes into a {type(data).__name__}")
    return data


class _Files:
    """Results files read once each, relative to the repository."""

    def __init__(self, root: Path):
        self.root, self.cache = root, {}

    def value(self, default_file: str, spec: str) -> float:
        """The number a spec names (its ``%`` applied)."""
        percent = spec.endswith("%")
        spec = spec.removesuffix("%")
        m = re.match(r"^[\w./-]+\.(?:json|csv):", spec)
        file, path = (spec[:m.end() - 1], spec[m.end():]) if m else (default_file, spec)
        if file not in self.cache:
            self.cache[file] = _load(self.root / file)
        value = resolve(self.cache[file], path)
        if isinstance(value, str):
            value = float(value)
        if not isinstance(value, (int, float)):
            raise KeyError(f"{path!r} is a {type(value).__name__}, not a number")
        return float(value) * (100.0 if percent else 1.0)


def _find(keys: list[str], key: str) -> int | None:
    """The index (0-based) of a row or column named by its text or by its number (1-based)."""
    if key in keys:
        return keys.index(key)
    if key.isdigit() and 1 <= int(key) <= len(keys):
        return int(key) - 1
    return None


def _expand(specs: list[str], row: str) -> list[str]:
    """The specs with ``{row}`` replaced by the row's key; a key of several words makes one spec per
    word (``row pose std = pose_std_ratio_female pose_std_ratio_male``)."""
    return [s.replace("{row}", word) for s in specs for word in (row.split() if "{row}" in s else [s])]


def _walk(table: MarkedTable, lines: list[str], files: _Files,
          visit: Callable[[int, int, re.Match, float | None, str], None]) -> list[str]:
    """Call ``visit(line, column, number, value, where)`` for every number of the table that a spec
    names (value None where the file lacks it); returns the problems that are not a number's value."""
    bad = []
    header = _split_row(lines[table.first])
    body = []
    for k in range(table.first + 2, len(lines)):
        if not lines[k].startswith("|"):
            break
        body.append(k)
    labels = [_split_row(lines[k])[0] for k in body]
    where0 = f"{table.page}:{table.marker + 1} ({table.file})"
    for name, keys, what in ((table.rows, labels, "row"), (table.cols, header, "column"), (table.heads, header, "column")):
        bad += [f"{where0}: no {what} {k!r} in the table" for k in name if _find(keys, k) is None]
    bad += [f"{where0}: no cell {r!r} | {c!r} in the table" for r, c in table.cells
            if _find(labels, r) is None or _find(header, c) is None]
    specs: dict[tuple[int, int], list[str]] = {}
    for rkey, rval in table.rows.items():
        r = _find(labels, rkey)
        for ckey, cspecs in table.cols.items():
            c = _find(header, ckey)
            if r is not None and c is not None:
                specs[(r, c)] = _expand(cspecs, rval)
    for (rkey, ckey), cspecs in table.cells.items():
        r, c = _find(labels, rkey), _find(header, ckey)
        if r is not None and c is not None:
            rval = next((v for k, v in table.rows.items() if _find(labels, k) == r), "{row}")
            specs[(r, c)] = _expand(cspecs, rval)
    jobs = [(body[r], c, [x.replace("{head}", header[c]) for x in s], f"row {labels[r]!r}, column {header[c]!r}")
            for (r, c), s in sorted(specs.items())]
    jobs += [(table.first, _find(header, k), s, f"header {k!r}") for k, s in table.heads.items() if _find(header, k) is not None]
    for line_no, c, cspecs, where in jobs:
        spans = _cell_spans(lines[line_no])
        if c >= len(spans):
            bad.append(f"{where0}: {where}: the line has {len(spans)} cells")
            continue
        a, b = spans[c]
        nums = numbers_in(lines[line_no][a:b])
        if len(nums) != len(cspecs):
            bad.append(f"{where0}: {where}: {len(nums)} numbers on the page "
                       f"({', '.join(n.group(0) for n in nums) or 'none'}), {len(cspecs)} specs")
            continue
        for num, spec in zip(nums, cspecs):
            if spec == "-":
                continue
            try:
                value = files.value(table.file, spec)
            except (KeyError, ValueError, FileNotFoundError) as e:
                bad.append(f"{where0}: {where}: {spec}: {e}")
                continue
            visit(line_no, a, num, value, f"{where0}: {where}: {spec}")
    return bad


def check_text(text: str, page: str = "<page>", root: Path = REPO) -> list[str]:
    """Every quoted number of the page's marked tables that differs from its file, and every marker
    that does not fit its table or file, one line each ('' list when all agree)."""
    lines, files, bad = text.splitlines(), _Files(root), []

    def visit(line_no, start, num, value, where):
        if not shows(num.group(0), value):
            bad.append(f"{where}: page {num.group(0)}, file {value:.6g}")

    for table in parse_markers(text, page):
        bad += _walk(table, lines, files, visit)
    return bad


def regenerate_text(text: str, page: str = "<page>", root: Path = REPO) -> tuple[str, list[str]]:
    """The page with every number of its marked tables that differs from its file rewritten with the
    file's value at the page's digits, and the list of changes (``where: old -> new``). Raises
    :class:`FormatError` when a marker does not fit its table or file."""
    lines, files = text.splitlines(keepends=True), _Files(root)
    edits: dict[int, list[tuple[int, int, str]]] = {}
    changes = []

    def visit(line_no, start, num, value, where):
        if not shows(num.group(0), value):
            new = format_like(num.group(0), value)
            edits.setdefault(line_no, []).append((start + num.start(), start + num.end(), new))
            changes.append(f"{where}: {num.group(0)} -> {new}")

    bare = [ln.rstrip("\n") for ln in lines]
    for table in parse_markers(text, page):
        bad = _walk(table, bare, files, visit)
        if bad:
            raise FormatError("\n".join(bad))
    for line_no, subs in edits.items():
        line = lines[line_no]
        for a, b, new in sorted(subs, reverse=True):
            line = line[:a] + new + line[b:]
        lines[line_no] = line
    return "".join(lines), changes


def marked_pages(root: Path = REPO) -> list[Path]:
    """The README and every page of docs/ that holds a numbers marker."""
    pages = [root / "README.md", *sorted((root / "docs").glob("*.md"))]
    return [p for p in pages if p.exists() and parse_markers(p.read_text(), str(p))]


def check_pages(root: Path = REPO) -> list[str]:
    """:func:`check_text` over every marked page of the README and docs/."""
    return [bad for page in marked_pages(root) for bad in check_text(page.read_text(), str(page.relative_to(root)), root)]


def regenerate_pages(root: Path = REPO) -> list[str]:
    """Rewrite (atomically) every marked page whose numbers differ from their files; the changes made."""
    changes = []
    for page in marked_pages(root):
        text, changed = regenerate_text(page.read_text(), str(page.relative_to(root)), root)
        if changed:
            write_text_atomic(page, text)
            changes += changed
    return changes


def checked_counts(text: str, page: str = "<page>", root: Path = REPO) -> list[tuple[MarkedTable, int]]:
    """Each marked table of the page with how many of its numbers a spec ties to a file (a marker that
    ties none checks nothing)."""
    lines, files, out = text.splitlines(), _Files(root), []
    for table in parse_markers(text, page):
        n = [0]
        _walk(table, lines, files, lambda *a: n.__setitem__(0, n[0] + 1))
        out.append((table, n[0]))
    return out
