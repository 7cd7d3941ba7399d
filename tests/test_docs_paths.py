"""Docs that stay true: every repository path named in the README, docs/, docstrings, comments and
configs exists, every link to a section of a page in docs/ names a heading of that page, and nothing
cites a tracker issue number (a reader cannot resolve one; say the reason, or link docs/decisions.md).

What counts as a repository path: a token that starts with ``convsynth_jax/``, ``experiments/``,
``conf/``, ``docs/``, ``tests/``, ``notebooks/`` or ``.ci/`` (optionally after ``../`` in a page of
docs/, resolved from that page), not preceded by a letter, digit, ``.``, ``/`` or ``-`` (so
``../shared/...`` or ``foo/tests/...`` do not count), and running over letters, digits and ``._/-``.
A ``#section`` suffix is checked as a heading of the page; trailing punctuation is dropped. Tokens
with a placeholder or glob (``*``, ``<name>``, ``{a,b}``, ``$VAR``, ``%s``) are patterns, not paths,
and are skipped. A file named relative to the package (``graph/seams.py``: a subpackage of
``convsynth_jax``, then a file with a suffix) must exist in the package or the repository, except in
docs/changelog.md, which records the old names of moved files.
"""
from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
_PREFIX = r"(?:convsynth_jax|experiments|conf|docs|tests|notebooks|\.ci)/"
_TOKEN = re.compile(r"(?<![\w./-])((?:\.\./)*" + _PREFIX + r"[\w./*{}<>$%+-]*(?:#[\w-]+)?)")
_MD_LINK = re.compile(r"\]\(([\w./-]*\.md)?#([\w-]+)\)")
# "issue 12", "Issues 3", "issue #12", "(#12)": never a CSS colour such as "#222;" or "#0a0a0a"
_TRACKER = re.compile(r"\b[Ii]ssues? ?#?\d+\b|(?<![\w&#])#\d{1,4}\b(?![;\w])")


def _files() -> list[Path]:
    out = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    for d in ("convsynth_jax", "experiments", "tests", "notebooks"):
        out += sorted(p for p in (ROOT / d).rglob("*.py") if ".venv" not in p.parts)
    out += sorted((ROOT / "conf").rglob("*.yaml"))
    out += [p for p in (ROOT / "pyproject.toml", ROOT / ".ci" / "run") if p.exists()]
    return [p for p in out if p != Path(__file__).resolve()]  # this file's examples are made up


def _anchor(heading: str) -> str:
    """GitHub's anchor of a Markdown heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"[^\w\s-]", "", heading.strip().lower())
    return re.sub(r"\s", "-", text)


def _anchors(page: Path) -> set[str]:
    return {_anchor(m.group(1)) for m in re.finditer(r"^#{1,6} (.+)$", page.read_text(), re.M)}


def named_paths(files: list[Path]) -> list[tuple[Path, int, str]]:
    """(file, line, missing path or path#anchor) for every named path that does not exist."""
    bad = []
    for f in files:
        for i, line in enumerate(f.read_text().splitlines(), 1):
            for m in _TOKEN.finditer(line):
                tok, _, anchor = m.group(1).partition("#")
                tok = tok.rstrip(".,:;)")
                if any(c in tok for c in "*{}<>$%"):
                    continue
                target = (f.parent if tok.startswith("../") else ROOT) / tok
                if not target.exists():
                    bad.append((f, i, tok))
                elif anchor and target.suffix == ".md" and anchor not in _anchors(target):
                    bad.append((f, i, f"{tok}#{anchor}"))
    return bad


def test_every_named_repository_path_exists():
    bad = named_paths(_files())
    assert not bad, "paths named but absent:\n" + "\n".join(f"{f.relative_to(ROOT)}:{i}: {t}" for f, i, t in bad)


_SUBPACKAGES = sorted(p.name for p in (ROOT / "convsynth_jax").iterdir() if p.is_dir() and not p.name.startswith("_"))
_PKG_TOKEN = re.compile(r"(?<![\w./-])((?:" + "|".join(_SUBPACKAGES) + r")/[\w./-]*\.(?:py|yaml|js|css|html))")


def package_paths(files: list[Path]) -> list[tuple[Path, int, str]]:
    """(file, line, path) for every file named relative to the package that is in neither the package
    nor the repository."""
    bad = []
    for f in files:
        for i, line in enumerate(f.read_text().splitlines(), 1):
            for m in _PKG_TOKEN.finditer(line):
                tok = m.group(1).rstrip(".")
                if not (ROOT / "convsynth_jax" / tok).exists() and not (ROOT / tok).exists():
                    bad.append((f, i, tok))
    return bad


def test_every_file_named_relative_to_the_package_exists():
    bad = package_paths([f for f in _files() if f != ROOT / "docs" / "changelog.md"])
    assert not bad, "package files named but absent:\n" + "\n".join(f"{f.relative_to(ROOT)}:{i}: {t}" for f, i, t in bad)


def test_the_rule_catches_a_missing_path_and_a_missing_section(tmp_path):
    page = tmp_path / "page.md"
    page.write_text("see `experiments/no_such_script.py`, `docs/decisions.md#no-such-section`, "
                    "`experiments/bench/*.py` and `docs/decisions.md#decisions`\n")
    bad = [t for _, _, t in named_paths([page])]
    assert bad == ["experiments/no_such_script.py", "docs/decisions.md#no-such-section"]
    page.write_text("`data/synthetic.py` moved to `data/synthetic/`; `graph/seams.py` and `conf/graph/default.yaml`\n")
    assert [t for _, _, t in package_paths([page])] == ["data/synthetic.py"]


@pytest.mark.parametrize("page", sorted((ROOT / "docs").glob("*.md")) + [ROOT / "README.md"], ids=lambda p: p.name)
def test_links_to_sections_name_a_heading(page):
    bad = []
    for i, line in enumerate(page.read_text().splitlines(), 1):
        for m in _MD_LINK.finditer(line):
            target = (page.parent / m.group(1)) if m.group(1) else page
            if target.exists() and m.group(2) not in _anchors(target):
                bad.append(f"{page.name}:{i}: {m.group(1) or ''}#{m.group(2)}")
    assert not bad, "links to missing sections:\n" + "\n".join(bad)


def test_no_tracker_issue_numbers():
    bad = [f"{f.relative_to(ROOT)}:{i}: {line.strip()[:100]}"
           for f in _files() for i, line in enumerate(f.read_text().splitlines(), 1) if _TRACKER.search(line)]
    assert not bad, "tracker references (say the reason or link docs/decisions.md):\n" + "\n".join(bad)
    assert _TRACKER.search("a comment (issue #14)") and _TRACKER.search("fixed in #31")
    assert not _TRACKER.search("color: #222; background: #0a0a0a")


def test_the_readme_is_a_page():
    """The README stays one page (at most 300 lines); methods, results and history live in docs/."""
    n = len((ROOT / "README.md").read_text().splitlines())
    assert n <= 300, f"README.md has {n} lines; move detail into docs/"


def test_the_docs_index_lists_every_page():
    """docs/README.md links every page of docs/ (pages it omitted were found only by search)."""
    docs = ROOT / "docs"
    index = (docs / "README.md").read_text()
    listed = set(re.findall(r"\]\(([\w.-]+\.md)\)", index))
    pages = {p.name for p in docs.glob("*.md") if p.name != "README.md"}
    assert pages - listed == set(), f"docs/README.md does not list {sorted(pages - listed)}"
