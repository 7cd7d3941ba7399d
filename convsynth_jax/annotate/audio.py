"""Audio segmentation (paper Section 4.2): words -> phonemic clauses (PC), listener responses (LR)
and hesitation pauses (HP); F0 with Praat; the peak of a segment is the time of its F0 maximum.

LR and HP come from an editable word corpus (``resources/word_corpus.yaml``): a token (or a
phrase of up to three tokens, matched greedily, longest first) in a list gets that label. Every run
of other words becomes a phonemic clause, split at pauses longer than ``max_gap`` seconds and at
LR/HP tokens. Note the ambiguity the paper accepts: a one-word answer such as "yeah" inside a turn
is labelled LR even when the speaker holds the floor.
"""
from __future__ import annotations

import logging
import re
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from ..errors import ConfigError, FormatError

log = logging.getLogger(__name__)

_DEFAULT_CORPUS = Path(__file__).resolve().parent.parent / "resources" / "word_corpus.yaml"
SEGMENT_COLUMNS = ["kind", "start", "peak", "end", "text"]


def normalize_word(w: str) -> str:
    w = str(w).strip().lower()
    return re.sub(r"[^\w%'\- ]", "", w)


def load_word_corpus(path: str | Path | None = None, extra: dict | None = None) -> dict:
    """{"listener_response": [...], "hesitation": [...]} from a YAML file (default: the shipped one)."""
    path = Path(path) if path else _DEFAULT_CORPUS
    try:
        data = yaml.safe_load(path.read_text()) or {}
    except FileNotFoundError:
        raise FormatError("word corpus not found", path) from None
    except yaml.YAMLError as e:
        raise FormatError(f"invalid YAML ({e})", path) from None
    out = {}
    for key in ("listener_response", "hesitation"):
        items = list(data.get(key, [])) + list((extra or {}).get(key, []) or [])
        out[key] = sorted({normalize_word(x) for x in items})
    overlap = set(out["listener_response"]) & set(out["hesitation"])
    if overlap:
        raise ConfigError(f"word corpus {path}: words in both lists: {sorted(overlap)}")
    return out


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


def segment_words(words: pd.DataFrame, corpus: dict | None = None, max_gap: float = 0.3,
                  max_clause_words: int | None = None) -> pd.DataFrame:
    """Words -> segments DataFrame[kind, start, end, text] (kind PC, LR or HP), in time order."""
    corpus = corpus or load_word_corpus()
    rows = []
    clause: list[int] = []

    def flush():
        if clause:
            rows.append({"kind": "PC", "start": float(words["start"].iat[clause[0]]),
                         "end": float(words["end"].iat[clause[-1]]),
                         "text": " ".join(str(words["word"].iat[k]) for k in clause)})
            clause.clear()

    for a, b, kind in _label_tokens(words, corpus):
        if kind == "W":
            if clause and (float(words["start"].iat[a]) - float(words["end"].iat[clause[-1]]) > max_gap
                           or (max_clause_words and len(clause) >= max_clause_words)):
                flush()
            clause.append(a)
            continue
        flush()
        rows.append({"kind": kind, "start": float(words["start"].iat[a]), "end": float(words["end"].iat[b - 1]),
                     "text": " ".join(str(words["word"].iat[k]) for k in range(a, b))})
    flush()
    df = pd.DataFrame(rows, columns=["kind", "start", "end", "text"])
    return df.sort_values("start", kind="stable").reset_index(drop=True)


def f0_contour(audio, time_step: float = 0.01, floor: float = 75.0, ceiling: float = 500.0):
    """(times (T,), f0 (T,) in Hz with NaN where unvoiced) from Praat's autocorrelation pitch tracker."""
    import parselmouth

    x = np.asarray(audio.samples, dtype=np.float64)
    if x.ndim > 1:
        x = x.mean(axis=1)
    snd = parselmouth.Sound(x, sampling_frequency=float(audio.sample_rate))
    pitch = snd.to_pitch(time_step=time_step, pitch_floor=floor, pitch_ceiling=ceiling)
    f0 = pitch.selected_array["frequency"].astype(np.float64)
    f0[f0 <= 0] = np.nan
    return np.asarray(pitch.xs(), dtype=np.float64), f0


def f0_contour_adaptive(audio, time_step: float = 0.01):
    """Two-pass F0 with a speaker-adapted range (De Looze & Hirst): a wide first pass (60-700 Hz),
    then floor = 0.72 * q35 and ceiling = 1.9 * q65 of the voiced values. Cuts octave jumps."""
    t, f = f0_contour(audio, time_step, 60.0, 700.0)
    v = f[np.isfinite(f)]
    if v.size < 20:
        return t, f
    floor = max(40.0, 0.72 * float(np.percentile(v, 35)))
    ceiling = max(floor * 2.0, 1.9 * float(np.percentile(v, 65)))
    return f0_contour(audio, time_step, floor, ceiling)


def local_peaks(times: np.ndarray, f0: np.ndarray, start: float, end: float) -> np.ndarray:
    """Times of all local maxima of the voiced F0 inside [start, end]."""
    m = (times >= start) & (times <= end)
    t, f = times[m], f0[m]
    if f.size < 3:
        return t[np.isfinite(f)][:1]
    g = np.where(np.isfinite(f), f, -np.inf)
    idx = np.flatnonzero((g[1:-1] > g[:-2]) & (g[1:-1] >= g[2:]) & np.isfinite(g[1:-1])) + 1
    return t[idx]


def add_peaks(segments: pd.DataFrame, times: np.ndarray, f0: np.ndarray) -> pd.DataFrame:
    """Add ``peak``: time of the F0 maximum inside each segment (its midpoint if wholly unvoiced),
    and ``f0_peak`` (Hz, NaN if unvoiced)."""
    seg = segments.copy()
    peaks, values = [], []
    for s, e in zip(seg["start"], seg["end"]):
        m = (times >= s) & (times <= e) & np.isfinite(f0)
        if m.any():
            k = int(np.argmax(np.where(m, f0, -np.inf)))
            peaks.append(float(times[k]))
            values.append(float(f0[k]))
        else:
            peaks.append(0.5 * (s + e))
            values.append(np.nan)
    seg["peak"] = peaks
    seg["f0_peak"] = values
    return seg[SEGMENT_COLUMNS + ["f0_peak"]]


def annotate_audio(words: pd.DataFrame, audio, cfg=None, word_corpus: dict | None = None) -> pd.DataFrame:
    """Segments DataFrame[kind, start, peak, end, text, f0_peak] of one participant's channel."""
    a = (cfg.get("annotate", cfg) if cfg is not None else {}) or {}
    corpus = word_corpus or load_word_corpus(a.get("word_corpus"), a.get("extra_words"))
    seg = segment_words(words, corpus, max_gap=float(a.get("max_gap", 0.3)),
                        max_clause_words=a.get("max_clause_words"))
    if audio is None:
        seg["peak"] = 0.5 * (seg["start"] + seg["end"])
        seg["f0_peak"] = np.nan
        return seg[SEGMENT_COLUMNS + ["f0_peak"]]
    step = float(a.get("f0_time_step", 0.01))
    if str(a.get("f0_range", "auto")) == "auto":
        times, f0 = f0_contour_adaptive(audio, step)
    else:
        times, f0 = f0_contour(audio, step, float(a.get("f0_floor", 75.0)), float(a.get("f0_ceiling", 500.0)))
    return add_peaks(seg, times, f0)
