"""Word-level transcript readers: Praat TextGrid (long and short text formats), TSV/CSV word
timings, IBM Watson Speech-to-Text JSON and the word-timestamped JSON of OpenAI Whisper
(``word_timestamps=True``), whisper-timestamped and WhisperX. All return a DataFrame with columns start, end, word
(seconds, sorted by start, validated). Writers: TSV (the GENEA layout) and the long TextGrid format."""
from __future__ import annotations

import json
import logging
import math
import re
from pathlib import Path

import pandas as pd

from ..errors import MissingFileError, TranscriptFormatError
from ..utils import atomic_path

log = logging.getLogger(__name__)

COLUMNS = ["start", "end", "word"]


def load_transcript(path: str | Path, tier: str = "words", fmt: str | None = None) -> pd.DataFrame:
    """Read a word-level transcript; the format comes from the extension unless ``fmt`` is given
    ('textgrid', 'tsv', 'csv', 'json')."""
    path = Path(path)
    if not path.is_file():
        raise MissingFileError("transcript file not found", path)
    fmt = (fmt or path.suffix.lstrip(".")).lower()
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError:
        try:
            text = path.read_text(encoding="utf-16")
        except UnicodeError as e:
            raise TranscriptFormatError(f"cannot decode text ({e})", path) from None
    if fmt == "textgrid":
        df = _parse_textgrid(text, tier, path)
    elif fmt in ("tsv", "txt", "lab"):
        df = _parse_delimited(text, "\t", path)
    elif fmt == "csv":
        df = _parse_delimited(text, ",", path)
    elif fmt == "json":
        df = _parse_json(text, path)
    else:
        raise TranscriptFormatError(f"unknown transcript format {fmt!r} (expected TextGrid, tsv, csv or json)", path)
    return validate_words(df, path)


def validate_words(df: pd.DataFrame, path: str | Path | None = None) -> pd.DataFrame:
    """Check times are finite, durations non-negative and words in temporal order."""
    df = df.reset_index(drop=True)
    for i, row in enumerate(df.itertuples(index=False)):
        if not (math.isfinite(row.start) and math.isfinite(row.end)):
            raise TranscriptFormatError(f"word {i} ({row.word!r}): non-finite time", path, f"word {i}")
        if row.end < row.start:
            raise TranscriptFormatError(f"word {i} ({row.word!r}): negative duration ({row.start} -> {row.end})",
                                        path, f"word {i}")
        if row.start < 0:
            raise TranscriptFormatError(f"word {i} ({row.word!r}): negative start time {row.start}", path, f"word {i}")
        if i and row.start < df.start.iat[i - 1] - 1e-6:
            raise TranscriptFormatError(
                f"word {i} ({row.word!r}) starts at {row.start} before word {i - 1} ({df.word.iat[i - 1]!r}) at "
                f"{df.start.iat[i - 1]}: words out of order", path, f"word {i}")
    return df[COLUMNS].astype({"start": float, "end": float, "word": str})


def _parse_delimited(text: str, sep: str, path: Path) -> pd.DataFrame:
    rows = []
    for lineno, line in enumerate(text.splitlines(), 1):
        if not line.strip():
            continue
        parts = [p.strip() for p in line.split(sep)]
        if lineno == 1 and [p.lower() for p in parts[:3]] == ["start", "end", "word"]:
            continue
        if len(parts) < 3:
            raise TranscriptFormatError(f"expected start{sep!r}end{sep!r}word, got {line!r}", path, f"line {lineno}")
        try:
            start, end = float(parts[0]), float(parts[1])
        except ValueError:
            raise TranscriptFormatError(f"non-numeric time in {line!r}", path, f"line {lineno}") from None
        if not (math.isfinite(start) and math.isfinite(end)):
            raise TranscriptFormatError(f"non-finite time in {line!r}", path, f"line {lineno}")
        if end < start:
            raise TranscriptFormatError(f"negative duration in {line!r}", path, f"line {lineno}")
        rows.append((start, end, sep.join(parts[2:]) if sep == "\t" else ",".join(parts[2:])))
    return pd.DataFrame(rows, columns=COLUMNS)


def _parse_json(text: str, path: Path) -> pd.DataFrame:
    """IBM Watson (``results``) or Whisper-family (``segments`` with ``words``, or WhisperX's
    ``word_segments``) JSON, told apart by their keys."""
    try:
        data = json.loads(text)
    except json.JSONDecodeError as e:
        raise TranscriptFormatError(f"invalid JSON ({e.msg})", path, f"line {e.lineno}") from None
    if isinstance(data, dict) and "results" in data:
        return _parse_ibm_json(data, path)
    if isinstance(data, dict) and ("word_segments" in data or "segments" in data):
        return _parse_whisper_json(data, path)
    raise TranscriptFormatError("expected IBM Watson Speech-to-Text JSON (a 'results' list) or Whisper/WhisperX "
                                "JSON with word timestamps (a 'segments' list with 'words', or 'word_segments')", path)


def _parse_ibm_json(data: dict, path: Path) -> pd.DataFrame:
    results = data.get("results")
    if not isinstance(results, list):
        raise TranscriptFormatError("'results' is not a list (expected IBM Watson Speech-to-Text JSON)", path)
    rows = []
    for r, res in enumerate(results):
        alts = res.get("alternatives") or []
        if not alts:
            continue
        for w, item in enumerate(alts[0].get("timestamps") or []):
            try:
                word, start, end = item[0], float(item[1]), float(item[2])
            except (TypeError, ValueError, IndexError):
                raise TranscriptFormatError(f"bad timestamp entry {item!r}", path,
                                            f"results[{r}].alternatives[0].timestamps[{w}]") from None
            rows.append((start, end, str(word)))
    return pd.DataFrame(rows, columns=COLUMNS)


def _parse_whisper_json(data: dict, path: Path) -> pd.DataFrame:
    """Words of Whisper-family JSON. WhisperX leaves ``start``/``end`` out for a token it could not align
    (often a numeral): such a word is dropped with a warning that counts them, since a clause can do
    without one word but a word without a time cannot be placed."""
    if "word_segments" in data:
        items = [(f"word_segments[{i}]", w) for i, w in enumerate(data["word_segments"] or [])]
    else:
        segs = data["segments"]
        if not isinstance(segs, list):
            raise TranscriptFormatError("'segments' is not a list", path)
        items = []
        for s, seg in enumerate(segs):
            words = seg.get("words") if isinstance(seg, dict) else None
            if words is None:
                raise TranscriptFormatError("segment without 'words': transcribe with word timestamps (Whisper's "
                                            "word_timestamps=True, or WhisperX's alignment)", path, f"segments[{s}]")
            items += [(f"segments[{s}].words[{i}]", w) for i, w in enumerate(words)]
    rows, unaligned = [], []
    for where, w in items:
        if not isinstance(w, dict) or "word" not in w:
            raise TranscriptFormatError(f"bad word entry {w!r} (expected an object with 'word', 'start', 'end')", path,
                                        where)
        if w.get("start") is None or w.get("end") is None:
            unaligned.append(f"{w['word'].strip()!r} ({where})")
            continue
        try:
            rows.append((float(w["start"]), float(w["end"]), str(w["word"]).strip()))
        except (TypeError, ValueError):
            raise TranscriptFormatError(f"bad time in word entry {w!r}", path, where) from None
    if unaligned:
        log.warning("%s: %d word(s) without start/end times dropped: %s", path, len(unaligned),
                    ", ".join(unaligned[:5]) + (" ..." if len(unaligned) > 5 else ""))
    return pd.DataFrame(rows, columns=COLUMNS)


_TOKEN = re.compile(r'"((?:[^"]|"")*)"|([^\s"]+)')


def _is_number(tok: str) -> bool:
    try:
        float(tok)
    except ValueError:
        return False
    return True


def _tokens(text: str):
    """Tokens of a TextGrid (both formats): quoted strings and bare words, with 'key =' and
    '[n]:' decorations of the long format removed. Yields (token, is_string, line)."""
    for lineno, line in enumerate(text.splitlines(), 1):
        for m in _TOKEN.finditer(line):
            if m.group(1) is not None:
                yield m.group(1).replace('""', '"'), True, lineno
            else:
                tok = m.group(2)
                # Bare tokens are keys in the long format (xmin, tiers?, item [1]:, ...): keep only
                # numbers and flags such as <exists>, which is all the short format has.
                if not (tok.startswith("<") or _is_number(tok)):
                    continue
                yield tok, False, lineno


def _parse_textgrid(text: str, tier: str, path: Path) -> pd.DataFrame:
    toks = list(_tokens(text))
    pos = 0

    def take(kind: str):
        nonlocal pos
        if pos >= len(toks):
            raise TranscriptFormatError(f"unexpected end of file while reading {kind}", path,
                                        f"line {toks[-1][2] if toks else 1}")
        t = toks[pos]
        pos += 1
        return t

    def number(kind: str) -> float:
        tok, is_str, line = take(kind)
        try:
            v = float(tok)
        except ValueError:
            raise TranscriptFormatError(f"expected a number for {kind}, got {tok!r}", path, f"line {line}") from None
        return v

    def count(kind: str) -> int:
        line = toks[pos][2] if pos < len(toks) else (toks[-1][2] if toks else 1)
        v = number(kind)
        if not (math.isfinite(v) and v >= 0 and v == int(v)):
            raise TranscriptFormatError(f"expected a whole number >= 0 for {kind}, got {v!r}", path, f"line {line}")
        return int(v)

    ftype, _, line = take("header")
    if ftype != "ooTextFile":
        raise TranscriptFormatError(f"not a Praat text file (starts with {ftype!r})", path, f"line {line}")
    oclass, _, line = take("object class")
    if oclass != "TextGrid":
        raise TranscriptFormatError(f"object class is {oclass!r}, expected 'TextGrid'", path, f"line {line}")
    number("xmin")
    number("xmax")
    tok, _, line = take("tiers flag")
    if tok != "<exists>":
        return pd.DataFrame(columns=COLUMNS)
    n_tiers = count("tier count")
    names = []
    for _ in range(n_tiers):
        tclass, _, line = take("tier class")
        tname, _, _ = take("tier name")
        names.append(tname)
        number("tier xmin")
        number("tier xmax")
        n = count("interval count")
        if tclass == "IntervalTier":
            rows = []
            for k in range(n):
                s = number(f"interval {k + 1} xmin")
                e = number(f"interval {k + 1} xmax")
                label, is_str, lline = take(f"interval {k + 1} text")
                if not is_str:
                    raise TranscriptFormatError(f"interval {k + 1}: expected quoted text, got {label!r}", path,
                                                f"line {lline}")
                if label.strip():
                    rows.append((s, e, label.strip()))
            if tname == tier:
                return pd.DataFrame(rows, columns=COLUMNS)
        elif tclass == "TextTier":
            for k in range(n):
                number(f"point {k + 1} time")
                take(f"point {k + 1} mark")
        else:
            raise TranscriptFormatError(f"unknown tier class {tclass!r}", path, f"line {line}")
    raise TranscriptFormatError(f"no tier named {tier!r}; tiers are {names}", path)


def save_transcript_tsv(words: pd.DataFrame, path: str | Path) -> Path:
    """Write start<TAB>end<TAB>word rows, no header (GENEA layout), atomically."""
    path = Path(path)
    lines = [f"{float(r.start):.3f}\t{float(r.end):.3f}\t{r.word}" for r in words.itertuples(index=False)]
    with atomic_path(path) as tmp:
        tmp.write_text("\n".join(lines) + ("\n" if lines else ""))
    return path


def _praat_number(x: float) -> str:
    """A time as Praat writes it: the shortest text that reads back to the same float, whole numbers
    without a decimal point."""
    text = repr(float(x))
    return text[:-2] if text.endswith(".0") else text


def textgrid_text(words: pd.DataFrame, duration: float | None = None, tier: str = "words") -> str:
    """A Praat long-format TextGrid with one interval tier ``tier`` holding the ``words`` (columns
    start, end, word; sorted) from 0 to ``duration`` (default: the last word's end). The gaps
    between words become empty intervals, as Praat requires intervals to tile the tier; a double
    quote in a word is doubled, Praat's escape."""
    intervals, t = [], 0.0
    for r in words.itertuples(index=False):
        if r.start > t + 1e-6:
            intervals.append((t, r.start, ""))
        intervals.append((r.start, r.end, str(r.word)))
        t = r.end
    duration = t if duration is None else duration
    if duration > t + 1e-6:
        intervals.append((t, duration, ""))
    end = _praat_number(duration)
    lines = ['File type = "ooTextFile"', 'Object class = "TextGrid"', "", "xmin = 0", f"xmax = {end}",
             "tiers? <exists>", "size = 1", "item []:", "    item [1]:", '        class = "IntervalTier"',
             f'        name = "{tier}"', "        xmin = 0", f"        xmax = {end}",
             f"        intervals: size = {len(intervals)}"]
    for i, (a, b, text) in enumerate(intervals, 1):
        escaped = text.replace('"', '""')
        lines += [f"        intervals [{i}]:", f"            xmin = {_praat_number(a)}",
                  f"            xmax = {_praat_number(b)}", f'            text = "{escaped}"']
    return "\n".join(lines) + "\n"


def save_textgrid(words: pd.DataFrame, path: str | Path, duration: float | None = None, tier: str = "words") -> Path:
    """Write :func:`textgrid_text` of ``words`` to ``path``, atomically."""
    path = Path(path)
    with atomic_path(path) as tmp:
        tmp.write_text(textgrid_text(words, duration, tier))
    return path
