"""Speech timing of recordings, measured with the annotation pipeline (``annotate.annotate_audio``):
the distributions the synthetic corpus is calibrated against (``docs/synthetic_corpus.md``).

Per channel (one speaker's words and audio) the pipeline gives phonemic clauses (PC), listener
responses (LR) and hesitations (HP) with their F0 peaks; from those and the word timings:

* ``clause_seconds``: duration of each phonemic clause (first word's start to last word's end);
* ``clause_words``: words per phonemic clause;
* ``peak_position``: the clause's F0 peak relative to the clause, (peak - start) / (end - start);
* ``clause_rate``: words per second within each clause (articulation rate);
* ``word_seconds``: duration of every word of a clause;
* ``pause_seconds``: silent gaps of at least ``PAUSE_MIN`` between consecutive words of one
  speaker while the partner says no clause (pauses within one's own speech, not turn changes);
* ``turn_gap_seconds``: floor-transfer offsets, from the end of one speaker's clause to the start of
  the other speaker's next clause when the clause-holder changes (negative: overlap); empty for
  monologues;
* ``fillers`` and ``words``: hesitation segments and words, for the filler rate per 100 words.

The pause threshold, the pooling and the turn-gap definition are ours.
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import stats

from ..annotate.audio import annotate_audio, word_corpus_for
from ..annotate.params import AnnotateParams
from ..errors import MissingFileError

PAUSE_MIN = 0.15  # s: a shorter silent gap between words is articulation, not a pause (ours)
DISTRIBUTIONS = ("clause_seconds", "clause_words", "peak_position", "clause_rate", "word_seconds",
                 "pause_seconds", "turn_gap_seconds")


@dataclass(frozen=True)
class SpeechTiming:
    """Pooled timing of one or more channels: each distribution field is a float64 array (one
    value per clause, word, pause or turn change; see the module docstring)."""

    clause_seconds: np.ndarray = field(default_factory=lambda: np.zeros(0))
    clause_words: np.ndarray = field(default_factory=lambda: np.zeros(0))
    peak_position: np.ndarray = field(default_factory=lambda: np.zeros(0))
    clause_rate: np.ndarray = field(default_factory=lambda: np.zeros(0))
    word_seconds: np.ndarray = field(default_factory=lambda: np.zeros(0))
    pause_seconds: np.ndarray = field(default_factory=lambda: np.zeros(0))
    turn_gap_seconds: np.ndarray = field(default_factory=lambda: np.zeros(0))
    words: int = 0
    fillers: int = 0
    seconds: float = 0.0  # recording time covered (sum over channels of sessions / recordings)

    @property
    def filler_rate(self) -> float:
        """Hesitations per 100 words."""
        return 100.0 * self.fillers / max(self.words, 1)

    def __add__(self, other: "SpeechTiming") -> "SpeechTiming":
        kw = {f.name: np.concatenate([getattr(self, f.name), getattr(other, f.name)]) for f in fields(self)
              if f.name in DISTRIBUTIONS}
        return SpeechTiming(**kw, words=self.words + other.words, fillers=self.fillers + other.fillers,
                            seconds=self.seconds + other.seconds)


def _gaps(words: pd.DataFrame) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(gap start, gap end, gap length) between consecutive words of one channel (sorted)."""
    st = words["start"].to_numpy(np.float64)
    en = words["end"].to_numpy(np.float64)
    a, b = en[:-1], st[1:]
    return a, b, b - a


def channel_timing(words: pd.DataFrame, segments: pd.DataFrame, partner_segments: pd.DataFrame | None = None,
                   seconds: float = 0.0) -> SpeechTiming:
    """Timing of one channel from its word table (DataFrame[start, end, word]) and its annotated
    segments (DataFrame[kind, start, peak, end], as ``annotate_audio`` returns them);
    ``partner_segments``: the other speaker's segments in a dialogue (pauses exclude gaps the
    partner's clauses fall into), None for a monologue."""
    words = words.sort_values("start", kind="stable").reset_index(drop=True)
    st = words["start"].to_numpy(np.float64)
    en = words["end"].to_numpy(np.float64)
    pc = segments[segments["kind"] == "PC"]
    s, e, p = (pc[c].to_numpy(np.float64) for c in ("start", "end", "peak"))
    length = e - s
    n_words = np.array([int(((st >= a - 1e-6) & (en <= b + 1e-6)).sum()) for a, b in zip(s, e)], np.float64)
    inside = np.zeros(st.size, bool)
    for a, b in zip(s, e):
        inside |= (st >= a - 1e-6) & (en <= b + 1e-6)
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.where(length > 0, (p - s) / length, 0.5)
        rate = np.where(length > 0, n_words / length, np.nan)
    ga, gb, gl = _gaps(words)
    pause = gl >= PAUSE_MIN
    if partner_segments is not None and len(partner_segments):
        other = partner_segments[partner_segments["kind"] == "PC"]
        os_, oe = other["start"].to_numpy(np.float64), other["end"].to_numpy(np.float64)
        for k in np.flatnonzero(pause):
            if ((os_ < gb[k]) & (oe > ga[k])).any():
                pause[k] = False
    return SpeechTiming(clause_seconds=length, clause_words=n_words, peak_position=rel,
                        clause_rate=rate[np.isfinite(rate)], word_seconds=(en - st)[inside],
                        pause_seconds=gl[pause], words=int(st.size),
                        fillers=int((segments["kind"] == "HP").sum()), seconds=float(seconds))


def turn_gaps(segments_a: pd.DataFrame, segments_b: pd.DataFrame) -> np.ndarray:
    """Floor-transfer offsets between two channels' phonemic clauses: for each clause whose speaker
    differs from the speaker of the clause that started before it, its start minus the end of that
    previous clause (negative: the turns overlap)."""
    rows = [(float(r.start), float(r.end), k) for k, seg in enumerate((segments_a, segments_b))
            for r in seg[seg["kind"] == "PC"].itertuples()]
    rows.sort()
    return np.array([b[0] - a[1] for a, b in zip(rows, rows[1:]) if a[2] != b[2]], np.float64)


def recording_timing(wav: str | Path, transcript: str | Path, params: AnnotateParams | None = None,
                     word_corpus: dict | None = None) -> SpeechTiming:
    """Timing of one monologue recording (a WAV and its word transcript, e.g. a TextGrid)."""
    from ..io import load_audio, load_transcript

    params = params or AnnotateParams()
    words = load_transcript(transcript)
    audio = load_audio(wav)
    seg = annotate_audio(words, audio, params, word_corpus=word_corpus or word_corpus_for(params))
    return channel_timing(words, seg, None, seconds=len(audio.samples) / float(audio.sample_rate))


def speech_folder_timing(folder: str | Path, params: AnnotateParams | None = None) -> SpeechTiming:
    """Pooled timing of every ``*.wav`` with a ``*.TextGrid`` beside it in ``folder`` (monologues)."""
    folder = Path(folder)
    pairs = [(w, w.with_suffix(".TextGrid")) for w in sorted(folder.glob("*.wav")) if w.with_suffix(".TextGrid").is_file()]
    if not pairs:
        raise MissingFileError("no *.wav with a *.TextGrid beside it", folder)
    params = params or AnnotateParams()
    corpus = word_corpus_for(params)
    out = SpeechTiming()
    for wav, tg in pairs:
        out = out + recording_timing(wav, tg, params, corpus)
    return out


def corpus_timing(corpus, params: AnnotateParams | None = None, sessions: int | None = None) -> SpeechTiming:
    """Pooled timing of a dyadic corpus (``io.load_corpus``: both channels of each session, audio
    and transcripts), of its first ``sessions`` sessions if given."""
    params = params or AnnotateParams()
    wc = word_corpus_for(params)
    out = SpeechTiming()
    for sess in corpus.sessions[:sessions]:
        words, segs, secs = [], [], []
        for p in sess.participants:
            w = p.load_transcript().sort_values("start", kind="stable").reset_index(drop=True)
            audio = p.load_audio()
            words.append(w)
            segs.append(annotate_audio(w, audio, params, word_corpus=wc))
            secs.append(len(audio.samples) / float(audio.sample_rate))
        for k in range(2):
            out = out + channel_timing(words[k], segs[k], segs[1 - k], seconds=secs[k])
        out = out + SpeechTiming(turn_gap_seconds=turn_gaps(segs[0], segs[1]))
    return out


def distribution_summary(x: np.ndarray) -> dict:
    """n, median, IQR (25th and 75th percentiles), 90th percentile, mean and max of ``x``."""
    x = np.asarray(x, np.float64)
    if x.size == 0:
        return {"n": 0}
    q = np.percentile(x, [25, 50, 75, 90])
    return {"n": int(x.size), "median": float(q[1]), "q25": float(q[0]), "q75": float(q[2]), "p90": float(q[3]),
            "mean": float(x.mean()), "max": float(x.max())}


def ks_distance(a: np.ndarray, b: np.ndarray) -> float:
    """Two-sample Kolmogorov-Smirnov distance (largest gap between the empirical CDFs); NaN if
    either sample is empty."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    if a.size == 0 or b.size == 0:
        return float("nan")
    return float(stats.ks_2samp(a, b).statistic)


def compare(real: SpeechTiming, synthetic: SpeechTiming) -> dict:
    """Per distribution: the summaries of both and their KS distance; and both filler rates."""
    out = {name: {"real": distribution_summary(getattr(real, name)), "synthetic": distribution_summary(getattr(synthetic, name)),
                  "ks": ks_distance(getattr(real, name), getattr(synthetic, name))} for name in DISTRIBUTIONS}
    out["fillers_per_100_words"] = {"real": real.filler_rate, "synthetic": synthetic.filler_rate}
    return out
