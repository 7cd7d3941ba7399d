"""Transcript readers: Praat TextGrid (long and short text formats read here, any other TextGrid Praat
reads, e.g. binary or chronological, through Praat itself via parselmouth), TSV/CSV (``start end word``
rows, or a header naming start, end and word or text columns), SubRip (.srt), WebVTT (.vtt), IBM Watson
Speech-to-Text JSON and the JSON of OpenAI Whisper, whisper-timestamped and WhisperX, with or without
word timestamps. All return a DataFrame with columns start, end, word (seconds, sorted by start,
validated). A row may hold several words (a subtitle, a sentence interval, a Whisper segment without
word timestamps): :func:`phrase_rows` finds them and :mod:`convsynth_jax.io.recognize` aligns them to
word timings against the audio. Writers: TSV (the GENEA layout) and the long TextGrid format."""
from __future__ import annotations

import json
import logging
import math
import re
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import MissingFileError, TranscriptFormatError
from ..utils import atomic_path

log = logging.getLogger(__name__)

COLUMNS = ["start", "end", "word"]


FORMATS = ("textgrid", "tsv", "txt", "lab", "csv", "json", "srt", "vtt")


def load_transcript(path: str | Path, tier: str = "words", fmt: str | None = None) -> pd.DataFrame:
    """Read a transcript; the format comes from the extension unless ``fmt`` is given ('textgrid',
    'tsv', 'csv', 'json', 'srt', 'vtt'). ``tier``: the TextGrid tier to read."""
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
            if fmt == "textgrid":  # e.g. Praat's binary format
                return validate_words(_read_textgrid_praat(path, tier), path)
            raise TranscriptFormatError(f"cannot decode text ({e})", path) from None
    if fmt == "textgrid":
        df = _read_textgrid(text, tier, path)
    elif fmt in ("tsv", "txt", "lab"):
        df = _parse_delimited(text, "\t", path)
    elif fmt == "csv":
        df = _parse_delimited(text, ",", path)
    elif fmt == "json":
        df = _parse_json(text, path)
    elif fmt == "srt":
        df = _parse_srt(text, path)
    elif fmt == "vtt":
        df = _parse_vtt(text, path)
    else:
        raise TranscriptFormatError(f"unknown transcript format {fmt!r} (expected TextGrid, tsv, csv, json, srt or vtt)",
                                    path)
    return validate_words(df, path)


def phrase_rows(words: pd.DataFrame) -> list[int]:
    """Indices of the rows holding several whitespace-separated words (phrases to align)."""
    return [i for i, w in enumerate(words["word"]) if len(str(w).split()) > 1]


_TAG = re.compile(r"<[^>]*>|\{[^}]*\}")


def _caption_text(text: str) -> str:
    """A subtitle's words on one line: markup (<i>, <v Speaker>, {\\an8}) removed, lines joined."""
    return " ".join(_TAG.sub(" ", text).split())


def _line_of(text: str, char: int) -> int:
    return text.count("\n", 0, max(0, char)) + 1


def _parse_srt(text: str, path: Path) -> pd.DataFrame:
    import srt

    try:
        subs = list(srt.parse(text))
    except srt.SRTParseError as e:
        raise TranscriptFormatError(f"not valid SubRip ({e})", path,
                                    f"line {_line_of(text, getattr(e, 'expected_start', 0))}") from None
    except ValueError as e:
        raise TranscriptFormatError(f"not valid SubRip ({e})", path) from None
    if not subs and text.strip():
        raise TranscriptFormatError("no subtitles found (expected numbered 'HH:MM:SS,mmm --> HH:MM:SS,mmm' cues)", path)
    rows = [(s.start.total_seconds(), s.end.total_seconds(), _caption_text(s.content)) for s in subs]
    return pd.DataFrame([r for r in rows if r[2]], columns=COLUMNS)


def _clock(stamp: str) -> float:
    """Seconds of a WebVTT time stamp ([HH:]MM:SS.mmm)."""
    secs = 0.0
    for part in str(stamp).strip().split(":"):
        secs = secs * 60 + float(part)
    return secs


def _parse_vtt(text: str, path: Path) -> pd.DataFrame:
    import webvtt

    try:
        caps = list(webvtt.from_string(text))
    except Exception as e:  # noqa: BLE001 - webvtt's MalformedFileError/MalformedCaptionError and its parser's own
        raise TranscriptFormatError(f"not valid WebVTT ({type(e).__name__}: {e})", path) from None
    if not caps and "-->" in text:
        raise TranscriptFormatError("no readable cue (expected 'HH:MM:SS.mmm --> HH:MM:SS.mmm' lines)", path)
    # webvtt-py's *_in_seconds are whole seconds: the times are read from the cue's text
    rows = [(_clock(c.start), _clock(c.end), _caption_text(c.text)) for c in caps]
    df = pd.DataFrame([r for r in rows if r[2]], columns=COLUMNS)
    return df.sort_values("start", kind="stable")


def validate_words(df: pd.DataFrame, path: str | Path | None = None) -> pd.DataFrame:
    """Check times are finite, durations non-negative and words in temporal order (the first bad word
    is named; the checks run on whole columns)."""
    df = df.reset_index(drop=True)
    start = df["start"].to_numpy(float)
    end = df["end"].to_numpy(float)
    bad = ~(np.isfinite(start) & np.isfinite(end)) | (end < start) | (start < 0)
    bad[1:] |= start[1:] < start[:-1] - 1e-6
    if bad.any():
        i = int(np.argmax(bad))
        w = df["word"].iat[i]
        if not (math.isfinite(start[i]) and math.isfinite(end[i])):
            why = ": non-finite time"
        elif end[i] < start[i]:
            why = f": negative duration ({start[i]} -> {end[i]})"
        elif start[i] < 0:
            why = f": negative start time {start[i]}"
        else:
            why = f" starts at {start[i]} before word {i - 1} ({df['word'].iat[i - 1]!r}) at {start[i - 1]}: words out of order"
        raise TranscriptFormatError(f"word {i} ({w!r}){why}", path, f"word {i}")
    return df[COLUMNS].astype({"start": float, "end": float, "word": str})


_START = ("start", "begin", "start_time", "starttime", "start_s", "onset", "from", "xmin", "tmin", "t0")
_END = ("end", "stop", "end_time", "endtime", "end_s", "offset", "to", "xmax", "tmax", "t1")
_WORD = ("word", "words", "text", "token", "label", "transcript", "sentence", "utterance", "content")


def _header_columns(parts: list[str], sep: str, path: Path) -> tuple[int, int, int] | None:
    """(start, end, word) column indices of a header line, None when the line is data (its first field a
    number); a header without one of them is an error naming the columns it has."""
    if not parts or _is_number(parts[0]) or not re.search(r"[A-Za-z]", parts[0]):
        return None
    names = [p.strip().strip('"').lower() for p in parts]

    def find(aliases, what):
        for a in aliases:
            if a in names:
                return names.index(a)
        raise TranscriptFormatError(f"the header names no {what} column (one of {', '.join(aliases[:4])}, ...); it has "
                                    f"{parts}", path, "line 1")
    return find(_START, "start"), find(_END, "end"), find(_WORD, "word or text")


def _row_times(start: str, end: str, row: str, path, where: str) -> tuple[float, float]:
    """(start, end) seconds of one delimited row: numeric, finite, not ending before it starts; else a
    TranscriptFormatError naming the file and ``where`` (its line) with the row."""
    try:
        t0, t1 = float(start), float(end)
    except ValueError:
        raise TranscriptFormatError(f"non-numeric time in {row!r}", path, where) from None
    if not (math.isfinite(t0) and math.isfinite(t1)):
        raise TranscriptFormatError(f"non-finite time in {row!r}", path, where)
    if t1 < t0:
        raise TranscriptFormatError(f"negative duration in {row!r}", path, where)
    return t0, t1


def _parse_delimited(text: str, sep: str, path: Path) -> pd.DataFrame:
    import csv

    lines = text.splitlines()
    first = next((i for i, line in enumerate(lines) if line.strip()), None)
    cols = None
    if first is not None:
        head = next(csv.reader([lines[first]], delimiter=sep))
        cols = _header_columns(head, sep, path)
    if cols is not None:
        # a header: the named columns, read as CSV/TSV (quoted fields may hold the separator)
        rows = []
        width = max(cols) + 1
        for k, parts in enumerate(csv.reader(lines[first + 1:], delimiter=sep), first + 2):
            if not any(p.strip() for p in parts):
                continue
            if len(parts) < width:
                raise TranscriptFormatError(f"{len(parts)} field(s), the header has {len(head)}", path, f"line {k}")
            start, end = _row_times(parts[cols[0]], parts[cols[1]], sep.join(parts), path, f"line {k}")
            word = parts[cols[2]].strip()
            if word:
                rows.append((start, end, word))
        return pd.DataFrame(rows, columns=COLUMNS)
    rows = []
    for lineno, line in enumerate(text.splitlines(), 1):
        if not line.strip():
            continue
        parts = [p.strip() for p in line.split(sep)]
        if len(parts) < 3:
            raise TranscriptFormatError(f"expected start{sep!r}end{sep!r}word, got {line!r}", path, f"line {lineno}")
        start, end = _row_times(parts[0], parts[1], line, path, f"line {lineno}")
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
                                "JSON (a 'segments' list, or WhisperX's 'word_segments')", path)


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
            if not isinstance(seg, dict):
                raise TranscriptFormatError(f"bad segment {seg!r} (expected an object)", path, f"segments[{s}]")
            words = seg.get("words")
            if words is None:
                # no word timestamps: the segment is a phrase (aligned to the audio by the caller)
                if "text" not in seg or "start" not in seg or "end" not in seg:
                    raise TranscriptFormatError("segment without 'words' and without 'start', 'end' and 'text'", path,
                                                f"segments[{s}]")
                items.append((f"segments[{s}]", {"word": str(seg["text"]), "start": seg["start"], "end": seg["end"]}))
                continue
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
            word = " ".join(str(w["word"]).split())
            if word:
                rows.append((float(w["start"]), float(w["end"]), word))
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
    """Tokens of a TextGrid (both formats): quoted strings (which may run over several lines, as
    Praat writes a label holding a line break) and bare words, with 'key =' and '[n]:' decorations
    of the long format removed. Yields (token, is_string, line of the token's start)."""
    line, at = 1, 0
    for m in _TOKEN.finditer(text):
        line += text.count("\n", at, m.start())
        at = m.start()
        if m.group(1) is not None:
            yield m.group(1).replace('""', '"'), True, line
        else:
            tok = m.group(2)
            # Bare tokens are keys in the long format (xmin, tiers?, item [1]:, ...): keep only
            # numbers and flags such as <exists>, which is all the short format has.
            if not (tok.startswith("<") or _is_number(tok)):
                continue
            yield tok, False, line


class _NotOurFormat(Exception):
    """The file is not one of the two text formats read here (binary, chronological, ...)."""


def _read_textgrid(text: str, tier: str, path: Path) -> pd.DataFrame:
    """The long and short text formats are read here (strict: a wrong count or a string where a number
    belongs is an error naming its line); any other TextGrid (binary, Praat's chronological format)
    is read by Praat itself through parselmouth, whose errors name the line too."""
    try:
        return _parse_textgrid(text, tier, path)
    except _NotOurFormat:
        return _read_textgrid_praat(path, tier)


def _read_textgrid_praat(path: Path, tier: str) -> pd.DataFrame:
    import parselmouth
    from parselmouth.praat import call

    try:
        tg = parselmouth.Data.read(str(path))
    except parselmouth.PraatError as e:
        why = " ".join(str(e).split("\n")[:2])
        raise TranscriptFormatError(f"neither a TextGrid text file nor one Praat reads (Praat: {why})", path) from None
    if not isinstance(tg, parselmouth.TextGrid):
        raise TranscriptFormatError(f"Praat reads a {type(tg).__name__}, not a TextGrid", path)
    names = [call(tg, "Get tier name", i) for i in range(1, call(tg, "Get number of tiers") + 1)]
    if tier not in names:
        raise TranscriptFormatError(f"no tier named {tier!r}; tiers are {names}", path)
    t = names.index(tier) + 1
    if not call(tg, "Is interval tier", t):
        raise TranscriptFormatError(f"tier {tier!r} is a point tier, not an interval tier of words", path)
    rows = []
    for i in range(1, call(tg, "Get number of intervals", t) + 1):
        label = call(tg, "Get label of interval", t, i).strip()
        if label:
            rows.append((call(tg, "Get start time of interval", t, i), call(tg, "Get end time of interval", t, i), label))
    return pd.DataFrame(rows, columns=COLUMNS)


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

    if not toks or toks[0][0] != "ooTextFile" or len(toks) < 2 or toks[1][0] != "TextGrid":
        raise _NotOurFormat()
    take("header")
    take("object class")
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
