"""Audio segmentation (paper Section 4.2): words -> phonemic clauses (PC), listener responses (LR)
and hesitation pauses (HP); F0 with Praat; the peak of a segment is the time of its F0 maximum.

LR and HP come from an editable word corpus (``resources/word_corpus.yaml``, or
``annotate.word_corpus`` in the config: a path or inline lists): a token (or a phrase of up to
three tokens, matched greedily, longest first) in a list gets that label. Every run of other words
becomes a phonemic clause, split at pauses longer than ``max_gap`` seconds, at LR/HP tokens and,
optionally, when a clause reaches ``max_clause_words`` words or ``max_clause_seconds``. With
``clause_method: prosodic`` (default) each such run is split further into clauses of one primary
stress from pauses, F0 resets, pre-boundary lengthening and prominence with a words-per-clause prior
(``annotate/clauses.py``); ``pause`` stops at the runs. The F0 track is octave-guarded
(``clauses.guard_f0``) before peaks are picked; a clause's peak is that of its stressed word.

Words in context (``word_context``, default): a listener response is a short turn, or a
backchannel, made of response words: a response word that follows a word of the speaker's own
clause within ``max_gap`` ("if I feel okay") belongs to that clause. A lexical filler ("like",
"well", "you know": also ordinary words) is a hesitation only when isolated or followed by a pause
(``filler_pause``) and never as a verb (after a pronoun, "to" or an auxiliary: "I like to"). Pure
fillers (um, uh, %HESITATION) are always hesitations.

F0 backends: Praat (praat-parselmouth, default) or openSMILE (eGeMAPS F0, optional: used only
when ``annotate.f0_backend: opensmile`` and the ``opensmile`` package is installed).
"""
from __future__ import annotations

import dataclasses
import logging
import re
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from ..errors import ConfigError, FormatError, TranscriptFormatError
from .params import AnnotateParams

log = logging.getLogger(__name__)

_DEFAULT_CORPUS = Path(__file__).resolve().parent.parent / "resources" / "word_corpus.yaml"
SEGMENT_COLUMNS = ["kind", "start", "peak", "end", "text"]


def normalize_word(w: str) -> str:
    w = str(w).strip().lower()
    return re.sub(r"[^\w%'\- ]", "", w)


WORD_CORPUS_KEYS = ("listener_response", "hesitation")


def load_word_corpus(path=None, extra: dict | None = None) -> dict:
    """{"listener_response": [...], "hesitation": [...]}: sorted lower-case words and phrases.

    ``path``: a YAML file with those two keys (default: the shipped ``resources/word_corpus.yaml``),
    or a mapping with the lists themselves (inline config). ``extra``: lists added to either key.
    """
    if path is not None and hasattr(path, "keys"):  # inline lists (a mapping)
        data, where = {k: path.get(k) for k in path.keys()}, "annotate.word_corpus"
    else:
        where = Path(path) if path else _DEFAULT_CORPUS
        try:
            data = yaml.safe_load(where.read_text()) or {}
        except FileNotFoundError:
            raise FormatError("word corpus not found", where) from None
        except yaml.YAMLError as e:
            raise FormatError(f"invalid YAML ({e})", where) from None
        if not isinstance(data, dict):
            raise FormatError(f"expected a mapping with keys {list(WORD_CORPUS_KEYS)}", where, "top level")
    unknown = set(data) - set(WORD_CORPUS_KEYS)
    if unknown:
        raise FormatError(f"unknown keys {sorted(unknown)}; expected {list(WORD_CORPUS_KEYS)}", where)
    out = {}
    for key in WORD_CORPUS_KEYS:
        items = list(data.get(key) or []) + list((extra or {}).get(key) or [])
        odd = [x for x in items if not isinstance(x, str)]
        if odd:  # e.g. a bare YAML yes/no, read as a boolean
            raise FormatError(f"entries must be strings, got {odd!r} (quote them)", where, key)
        words = {normalize_word(x) for x in items}
        if "" in words:
            raise FormatError("empty word in the list", where, key)
        out[key] = sorted(words)
    overlap = set(out["listener_response"]) & set(out["hesitation"])
    if overlap:
        raise ConfigError(f"words in both lists: {sorted(overlap)}", where)
    return out


def word_corpus_for(params: AnnotateParams) -> dict:
    """The word corpus the annotation parameters ask for."""
    return load_word_corpus(params.word_corpus, params.extra_words)


def check_words(words: pd.DataFrame) -> None:
    """Raise TranscriptFormatError (naming the transcript file from ``words.attrs['path']`` when
    known, and the word) unless words has start <= end, finite times and non-empty words."""
    path = words.attrs.get("path") if hasattr(words, "attrs") else None
    missing = {"start", "end", "word"} - set(words.columns)
    if missing:
        raise TranscriptFormatError(f"word table lacks columns {sorted(missing)}", path)
    st = pd.to_numeric(words["start"], errors="coerce").to_numpy(np.float64)
    en = pd.to_numeric(words["end"], errors="coerce").to_numpy(np.float64)
    bad = np.flatnonzero(~np.isfinite(st) | ~np.isfinite(en) | (en < st))
    if bad.size:
        i = int(bad[0])
        raise TranscriptFormatError(f"expected finite times with start <= end, got start={words['start'].iat[i]!r}, "
                                    f"end={words['end'].iat[i]!r}", path, f"word {i} ({words['word'].iat[i]!r})")


def _label_tokens(words: pd.DataFrame, corpus: dict) -> list[tuple[int, int, str]]:
    """Greedy phrase matching: [(first word index, last word index + 1, 'LR'|'HP'|'W')]."""
    lookup = {}
    for kind, key in (("LR", "listener_response"), ("HP", "hesitation")):
        for phrase in corpus[key]:
            lookup[tuple(phrase.replace("-", " - ").split())] = kind
            lookup[tuple(phrase.split())] = kind
    toks = [normalize_word(w) for w in words["word"]]
    out, i = [], 0
    while i < len(toks):
        for n in (3, 2, 1):
            if i + n <= len(toks) and tuple(" ".join(toks[i:i + n]).split()) in lookup:
                out.append((i, i + n, lookup[tuple(" ".join(toks[i:i + n]).split())]))
                i += n
                break
        else:
            out.append((i, i + 1, "W"))
            i += 1
    return out


# A lexical filler right after one of these is a verb or an object ("I like", "to like", "you
# know", "do you know", "as well"), not a hesitation.
_VERB_CUES = frozenset("i you we they he she it who that to would 'd do does did don't doesn't didn't "
                       "can can't will won't should could might must really also just not never as "
                       "very pretty".split())


def _in_context(words: pd.DataFrame, tokens: list, max_gap: float, filler_pause: float,
                lexical_fillers) -> list:
    """Relabel the (first, last + 1, kind) tokens of _label_tokens by context (module docstring):
    an LR token continuing one's own clause and a lexical filler used as a word become 'W'."""
    st = words["start"].to_numpy(np.float64)
    en = words["end"].to_numpy(np.float64)
    toks = [normalize_word(w) for w in words["word"]]
    lexical = {" ".join(normalize_word(x).replace("-", " ").split()) for x in lexical_fillers}
    out = []
    for t, (a, b, kind) in enumerate(tokens):
        prev = out[-1] if out else None
        gap_before = st[a] - en[prev[1] - 1] if prev else np.inf
        gap_after = st[tokens[t + 1][0]] - en[b - 1] if t + 1 < len(tokens) else np.inf
        if kind == "LR" and prev is not None and prev[2] == "W" and gap_before <= max_gap:
            kind = "W"  # inside the speaker's own clause
        elif kind == "HP" and " ".join(" ".join(toks[a:b]).replace("-", " ").split()) in lexical:
            verb = prev is not None and gap_before <= max_gap and toks[prev[1] - 1] in _VERB_CUES
            paused = gap_after >= filler_pause or (t + 1 < len(tokens) and tokens[t + 1][2] == "HP")
            if verb or not paused:
                kind = "W"
        out.append((a, b, kind))
    return out


CLAUSE_METHODS = ("prosodic", "pause")


def segment_words(words: pd.DataFrame, corpus: dict | None = None, max_gap: float = 0.3,
                  max_clause_words: int | None = None, max_clause_seconds: float | None = None,
                  params: AnnotateParams | None = None, prosody=None) -> pd.DataFrame:
    """Words DataFrame[start, end, word] (seconds) -> segments DataFrame[kind, start, end, text]
    (kind PC, LR or HP), in time order. A clause is closed before a word that follows a pause longer
    than ``max_gap`` s, or that would make it longer than ``max_clause_words`` / ``max_clause_seconds``.
    ``params`` (default AnnotateParams()) gives the word-context rules (word_context, filler_pause,
    lexical_fillers) and the clause method: ``prosodic`` (default) splits each such clause further
    at prosodic boundaries (``annotate/clauses.py``), from ``prosody`` (a ``WordProsody`` of the
    words sorted by start; default: durations and pauses only, as without audio)."""
    from .clauses import boundary_evidence, split_run, word_prosody

    corpus = corpus or load_word_corpus()
    p = params or AnnotateParams()
    if p.clause_method not in CLAUSE_METHODS:
        raise ConfigError(f"annotate.clause_method must be one of {list(CLAUSE_METHODS)}, got {p.clause_method!r}")
    check_words(words)
    words = words.sort_values("start", kind="stable").reset_index(drop=True)
    tokens = _label_tokens(words, corpus)
    if p.word_context:
        tokens = _in_context(words, tokens, max_gap, p.filler_pause, p.lexical_fillers)
    prosodic = p.clause_method == "prosodic"
    if prosodic and prosody is None:
        prosody = word_prosody(words)
    if prosodic and prosody.prominence.size != len(words):
        raise ConfigError(f"word prosody has {prosody.prominence.size} words, the transcript {len(words)}",
                          words.attrs.get("path"))
    limit = min(p.clause_max_words, max_clause_words or p.clause_max_words)
    if prosodic and limit < 1:
        raise ConfigError(f"annotate.clause_max_words must be >= 1, got {p.clause_max_words}")
    starts = words["start"].to_numpy(np.float64)
    ends = words["end"].to_numpy(np.float64)
    rows = []
    clause: list[int] = []

    def emit(idx):
        rows.append({"kind": "PC", "start": float(starts[idx[0]]), "end": float(ends[idx[-1]]),
                     "text": " ".join(str(words["word"].iat[k]) for k in idx)})

    def flush():
        if not clause:
            return
        if prosodic and len(clause) > 1:
            idx = np.asarray(clause)
            ev = boundary_evidence(words, idx, prosody, p)
            pr = dataclasses.replace(p, max_clause_seconds=max_clause_seconds)
            for i, j in split_run(ev, prosody.prominence[idx], (starts[idx], ends[idx]), pr, limit):
                emit(clause[i:j])
        else:
            emit(list(clause))
        clause.clear()

    for a, b, kind in tokens:
        if kind == "W":
            if clause and (float(words["start"].iat[a]) - float(words["end"].iat[clause[-1]]) > max_gap
                           or (not prosodic and max_clause_words and len(clause) >= max_clause_words)
                           or (not prosodic and max_clause_seconds
                               and float(words["end"].iat[a]) - float(words["start"].iat[clause[0]])
                               > max_clause_seconds)):
                flush()
            clause.extend(range(a, b))  # a phrase taken back into the clause keeps all its words
            continue
        flush()
        rows.append({"kind": kind, "start": float(words["start"].iat[a]), "end": float(words["end"].iat[b - 1]),
                     "text": " ".join(str(words["word"].iat[k]) for k in range(a, b))})
    flush()
    df = pd.DataFrame(rows, columns=["kind", "start", "end", "text"])
    return df.sort_values("start", kind="stable").reset_index(drop=True)


def f0_contour(audio, time_step: float = 0.01, floor: float = 75.0, ceiling: float = 500.0,
               octave_jump_cost: float = 0.35):
    """(times (T,), f0 (T,) in Hz with NaN where unvoiced) from Praat's autocorrelation pitch tracker
    (``octave_jump_cost``: Praat's penalty on frame-to-frame octave jumps; its default is 0.35)."""
    import parselmouth

    x = np.asarray(audio.samples, dtype=np.float64)
    if x.ndim > 1:
        x = x.mean(axis=1)
    snd = parselmouth.Sound(x, sampling_frequency=float(audio.sample_rate))
    pitch = snd.to_pitch_ac(time_step=time_step, pitch_floor=floor, pitch_ceiling=ceiling,
                            octave_jump_cost=octave_jump_cost)
    f0 = pitch.selected_array["frequency"].astype(np.float64)
    f0[f0 <= 0] = np.nan
    return np.asarray(pitch.xs(), dtype=np.float64), f0


def f0_contour_opensmile(audio):
    """(times (T,), f0 (T,) Hz, NaN where unvoiced) from openSMILE's eGeMAPS F0 (10 ms hop, 60 ms
    frames; times are frame centres). Needs the optional ``opensmile`` package."""
    try:
        import opensmile
    except ImportError:
        raise ConfigError("annotate.f0_backend=opensmile needs the optional package: pip install opensmile") from None
    x = np.asarray(audio.samples, dtype=np.float32)
    if x.ndim > 1:
        x = x.mean(axis=1)
    smile = opensmile.Smile(feature_set=opensmile.FeatureSet.eGeMAPSv02,
                            feature_level=opensmile.FeatureLevel.LowLevelDescriptors)
    df = smile.process_signal(x, int(audio.sample_rate))
    st = df["F0semitoneFrom27.5Hz_sma3nz"].to_numpy(np.float64)
    starts = df.index.get_level_values("start").total_seconds().to_numpy()
    f0 = np.where(st > 0, 27.5 * 2.0 ** (st / 12.0), np.nan)  # semitones above 27.5 Hz -> Hz
    # eGeMAPS computes F0 on 60 ms frames that start where the index says: centre = start + 30 ms
    return starts + 0.03, f0


def f0_contour_adaptive(audio, time_step: float = 0.01, octave_jump_cost: float = 0.35):
    """Two-pass F0 with a speaker-adapted range (De Looze & Hirst): a wide first pass (60-700 Hz),
    then floor = 0.72 * q35 and ceiling = 1.9 * q65 of the voiced values. Cuts octave jumps."""
    t, f = f0_contour(audio, time_step, 60.0, 700.0, octave_jump_cost)
    v = f[np.isfinite(f)]
    if v.size < 20:
        return t, f
    floor = max(40.0, 0.72 * float(np.percentile(v, 35)))
    ceiling = max(floor * 2.0, 1.9 * float(np.percentile(v, 65)))
    return f0_contour(audio, time_step, floor, ceiling, octave_jump_cost)


def local_peaks(times: np.ndarray, f0: np.ndarray, start: float, end: float) -> np.ndarray:
    """Times of all local maxima of the voiced F0 inside [start, end] (times, f0: (T,); a plateau
    counts once, at its first sample; a lone voiced sample counts as a maximum)."""
    m = (times >= start) & (times <= end)
    t, f = times[m], f0[m]
    if f.size < 3:
        return t[np.isfinite(f)][:1]
    g = np.where(np.isfinite(f), f, -np.inf)
    idx = np.flatnonzero((g[1:-1] > g[:-2]) & (g[1:-1] >= g[2:]) & np.isfinite(g[1:-1])) + 1
    return t[idx]


def add_peaks(segments: pd.DataFrame, times: np.ndarray, f0: np.ndarray, raw: np.ndarray | None = None,
              dropped: np.ndarray | None = None, windows: list | None = None) -> pd.DataFrame:
    """Add ``peak``: time of the F0 maximum inside each segment (its midpoint if wholly unvoiced),
    ``f0_peak`` (Hz, NaN if unvoiced) and ``f0_suspect``. times, f0: (T,). ``windows``: per segment
    a (start, end) to look in first (a clause's stressed word), else the whole segment. ``raw`` and
    ``dropped`` (T,): the unguarded track and the frames the octave guard removed; a segment is
    suspect when the unguarded track would have put its peak on a removed frame (an octave jump)."""
    seg = segments.copy()
    peaks, values, suspect = [], [], []
    ok = np.isfinite(f0)
    for r, (s, e) in enumerate(zip(seg["start"], seg["end"])):
        m = (times >= s) & (times <= e)
        look = m & ok
        if windows is not None and windows[r] is not None:
            w = (times >= windows[r][0]) & (times <= windows[r][1]) & ok
            look = w if w.any() else look
        if look.any():
            k = int(np.argmax(np.where(look, f0, -np.inf)))
            peaks.append(float(times[k]))
            values.append(float(f0[k]))
        else:
            peaks.append(0.5 * (s + e))
            values.append(np.nan)
        sus = False
        if raw is not None and dropped is not None:
            d = m & dropped
            sus = bool(d.any() and (not np.isfinite(values[-1]) or np.nanmax(raw[d]) > values[-1]))
        suspect.append(sus)
    seg["peak"] = peaks
    seg["f0_peak"] = values
    seg["f0_suspect"] = suspect
    return seg[SEGMENT_COLUMNS + ["f0_peak", "f0_suspect"]]


def f0_track(audio, params: AnnotateParams):
    """(times, f0) with the backend and range the annotation parameters ask for."""
    if params.f0_backend == "opensmile":
        return f0_contour_opensmile(audio)
    if params.f0_backend != "praat":
        raise ConfigError(f"annotate.f0_backend must be 'praat' or 'opensmile', got {params.f0_backend!r}")
    if params.f0_range == "auto":
        return f0_contour_adaptive(audio, params.f0_time_step, params.f0_octave_jump_cost)
    if params.f0_range != "fixed":
        raise ConfigError(f"annotate.f0_range must be 'auto' or 'fixed', got {params.f0_range!r}")
    return f0_contour(audio, params.f0_time_step, params.f0_floor, params.f0_ceiling, params.f0_octave_jump_cost)


def annotate_audio(words: pd.DataFrame, audio, params: AnnotateParams, word_corpus: dict | None = None) -> pd.DataFrame:
    """Segments DataFrame[kind, start, peak, end, text, f0_peak, f0_suspect] (seconds; f0_peak in
    Hz) of one participant's channel. ``audio`` None: peaks at segment midpoints and clauses from
    word timings alone. The F0 track is octave-guarded (``clauses.guard_f0``); a clause's peak is
    the F0 maximum of its most prominent (stressed) word; ``f0_suspect`` marks segments whose
    unguarded peak was an octave jump (a warning counts them)."""
    from .clauses import energy_contour, guard_f0, word_prosody

    corpus = word_corpus or word_corpus_for(params)
    check_words(words)
    words = words.sort_values("start", kind="stable").reset_index(drop=True)
    seg_kw = dict(max_gap=params.max_gap, max_clause_words=params.max_clause_words,
                  max_clause_seconds=params.max_clause_seconds or None, params=params)
    if audio is None:
        seg = segment_words(words, corpus, **seg_kw)
        seg["peak"] = 0.5 * (seg["start"] + seg["end"])
        seg["f0_peak"] = np.nan
        seg["f0_suspect"] = False
        return seg[SEGMENT_COLUMNS + ["f0_peak", "f0_suspect"]]
    times, f0 = f0_track(audio, params)
    g = guard_f0(times, f0, params)
    pros = word_prosody(words, g, energy_contour(audio, params.f0_time_step))
    seg = segment_words(words, corpus, prosody=pros, **seg_kw)
    st = words["start"].to_numpy(np.float64)
    en = words["end"].to_numpy(np.float64)
    windows = []
    for kind, s, e in zip(seg["kind"], seg["start"], seg["end"]):
        idx = np.flatnonzero((st >= s - 1e-9) & (en <= e + 1e-9))
        if kind == "PC" and params.clause_method == "prosodic" and idx.size:
            k = int(idx[int(np.argmax(pros.prominence[idx]))])
            windows.append((st[k], en[k]))
        else:
            windows.append(None)
    out = add_peaks(seg, times, g.f0, g.raw, g.dropped, windows)
    n_sus = int(out["f0_suspect"].sum())
    if n_sus:
        log.warning("%s: %d of %d segment F0 peaks were octave jumps of the tracker (speaker median %.0f Hz); "
                    "used the guarded peaks (column f0_suspect)",
                    words.attrs.get("path") or getattr(audio, "path", "") or "audio", n_sus,
                    len(out), g.median)
    return out
