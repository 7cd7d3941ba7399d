"""Phonemic clauses from prosody (paper Section 4.2; docs/decisions.md#phonemic-clauses-from-prosody), and the F0 octave guard.

The paper's phonemic clause is "a group of words that has a strongly stressed word" (mean 4.29 +-
2.16 words for the female character, 3.86 +- 1.36 for the male). Pause-delimited runs of words are
only an upper bound: fluent speech runs 10-40 words without a pause. Here every pause-delimited run
(``annotate.max_gap``, the ``pause`` method's clauses) is split further by a dynamic program over the
boundary positions between its words that maximizes

    sum over clauses   prior_weight * log P(words in clause)          (words-per-clause prior)
                     - w_stress * max(0, 2nd-largest prominence - stress_z)   (one primary stress:
                     - w_stress * max(0, stress_z - largest prominence)        not two, not none)
  + sum over the boundaries it places   evidence(boundary) - boundary_bias

with at most ``clause_max_words`` words per clause (a hard limit). The evidence of a boundary after
word k (all terms ours; weights in ``AnnotateParams``):

* pause: the silent gap after word k, relative to ``max_gap`` (capped at 1);
* F0 reset: the jump up (semitones) from the end of word k to the start of words k+1 and k+2 (the
  lower of the two, so that the rise into a pitch accent on word k+1 is no reset: a new declination
  line starts high on both), capped at +-1 after dividing by ``clause_reset_semitones``;
* pre-boundary lengthening: log of word k's duration over the speaker's mean duration for a word of
  its syllable count (syllables estimated from vowel groups), relative to log 1.5, capped at +-1;
* a small lexical cue: no boundary right after an article, preposition, pronoun subject or
  conjunction (``the``, ``of``, ``I`` ... cannot end a clause).

Prominence of a word: the mean of z-scores (over the speaker's words) of its F0 maximum (counted
twice), its energy maximum and its log duration ratio; the clause's stressed word is its most
prominent word, and the clause's F0 peak is the F0 maximum of that word.

F0 octave guard (``guard_f0``): pitch trackers halve or double F0 for a few frames (creak, weak
harmonics), which made segment peaks of 300-350 Hz for a speaker with a 176 Hz median. Frames more
than ``f0_guard_octaves`` from the speaker's median over the whole recording, or more than
``f0_jump_semitones`` from the running median of the contour (``f0_median_window`` s), are dropped;
so are frames at least ``f0_near_octave_semitones`` (10) from the median that lie outside the
speaker's own range (its 5th to 95th percentile, ``f0_range_quantile``): a doubled stretch longer
than the running median's window (a male speaker with a 165 Hz median and a 224 Hz 95th
percentile got a 323 Hz clause peak without this rule);
peaks are picked on the remaining contour after a ``f0_smooth_frames`` median filter. Praat's own
octave-jump cost (``f0_octave_jump_cost``) already penalizes such jumps inside the tracker.
"""
from __future__ import annotations

import re
import warnings
from dataclasses import dataclass

import numpy as np
import pandas as pd

from .params import AnnotateParams

# words after which a clause does not end (ours): articles, prepositions, subject pronouns,
# conjunctions, auxiliaries that need a complement
_PROCLITICS = frozenset(
    "a an the of to in on at for from with by into about as and or but so if that than because "
    "i we you he she they it i'm we're you're they're he's she's it's there's here's my your our their his "
    "her its is are was were am be been do does did have has had will would can could should must "
    "very really just not no this these those some".split())


# ------------------------------------------------------------------------------------ F0 guard
def _nan_median_filter(x: np.ndarray, width: int) -> np.ndarray:
    """Running median of the finite values of x (T,) over ``width`` frames (odd); NaN stays NaN."""
    if width <= 1 or x.size == 0:
        return x.copy()
    h = width // 2
    pad = np.concatenate([np.full(h, np.nan), x, np.full(h, np.nan)])
    win = np.lib.stride_tricks.sliding_window_view(pad, 2 * h + 1)
    with warnings.catch_warnings():  # all-NaN windows (unvoiced stretches) give NaN quietly
        warnings.simplefilter("ignore", RuntimeWarning)
        med = np.nanmedian(win, axis=1)
    return np.where(np.isfinite(x), med, np.nan)


@dataclass(frozen=True)
class GuardedF0:
    """A guarded F0 track. times, raw, f0: (T,) (Hz, NaN where unvoiced); f0 is the guarded,
    median-filtered contour used for peaks; dropped: (T,) bool, voiced frames the guard removed;
    median: the speaker's median F0 (Hz) over the whole recording (NaN if nothing is voiced)."""

    times: np.ndarray
    raw: np.ndarray
    f0: np.ndarray
    dropped: np.ndarray
    median: float


def guard_f0(times: np.ndarray, f0: np.ndarray, params: AnnotateParams) -> GuardedF0:
    """Drop octave jumps from an F0 track (module docstring): frames outside median +-
    ``f0_guard_octaves``, frames near an octave off the median and outside the speaker's own range,
    and frames off the running median by more than ``f0_jump_semitones``."""
    raw = np.asarray(f0, np.float64)
    voiced = np.isfinite(raw) & (raw > 0)
    if voiced.sum() < 3:
        return GuardedF0(times, raw, np.where(voiced, raw, np.nan), np.zeros(raw.shape, bool),
                         float(np.median(raw[voiced])) if voiced.any() else float("nan"))
    med = float(np.median(raw[voiced]))
    st = np.where(voiced, 12.0 * np.log2(np.where(voiced, raw, 1.0) / med), np.nan)
    keep = voiced & (np.abs(st) <= 12.0 * params.f0_guard_octaves)
    # near an octave off the median and outside the speaker's own range: a doubled (halved) stretch
    q = float(params.f0_range_quantile)
    lo, hi = np.quantile(raw[voiced], [q, 1.0 - q])
    keep &= ~((np.abs(st) >= params.f0_near_octave_semitones) & ((raw > hi) | (raw < lo)))
    dt = float(np.median(np.diff(times))) if times.size > 1 else 0.01
    width = max(1, int(round(params.f0_median_window / dt))) | 1
    local = _nan_median_filter(np.where(keep, st, np.nan), width)
    keep &= np.abs(st - np.where(np.isfinite(local), local, st)) <= params.f0_jump_semitones
    clean = np.where(keep, raw, np.nan)
    smooth = _nan_median_filter(clean, max(1, int(params.f0_smooth_frames)) | 1)
    return GuardedF0(times, raw, smooth, voiced & ~keep, med)


# ---------------------------------------------------------------------------- word prosody
def syllables(word: str) -> int:
    """Rough syllable count of an English word from its vowel groups (at least 1)."""
    w = re.sub(r"[^a-z]", "", str(word).lower())
    if not w:
        return 1
    n = len(re.findall(r"[aeiouy]+", w))
    if w.endswith("e") and not w.endswith(("le", "ee", "ye")) and n > 1:
        n -= 1
    return max(1, n)


@dataclass(frozen=True)
class WordProsody:
    """Per-word prosodic features of one speaker's transcript (W words, in the transcript's order
    after sorting by start): f0_max, f0_low (semitones re the speaker median; NaN if unvoiced),
    energy (dB, NaN without audio), dur_ratio (duration / the speaker's mean for that many
    syllables), prominence (z-score mean, see module docstring); f0_start, f0_end: median F0
    (semitones) of the first / last 30% of the word's voiced frames."""

    f0_max: np.ndarray
    f0_low: np.ndarray
    f0_start: np.ndarray
    f0_end: np.ndarray
    energy: np.ndarray
    dur_ratio: np.ndarray
    prominence: np.ndarray


def energy_contour(audio, time_step: float = 0.01, window: float = 0.025):
    """(times (T,), frame RMS energy in dB (T,)) of ``audio`` (mono mix), frames centred on times."""
    x = np.asarray(audio.samples, dtype=np.float64)
    if x.ndim > 1:
        x = x.mean(axis=1)
    sr = float(audio.sample_rate)
    hop, win = max(1, int(round(time_step * sr))), max(2, int(round(window * sr)))
    if x.size < win:
        return np.zeros(0), np.zeros(0)
    frames = np.lib.stride_tricks.sliding_window_view(x, win)[::hop]
    rms = np.sqrt(np.mean(frames ** 2, axis=1))
    times = (np.arange(frames.shape[0]) * hop + win / 2) / sr
    return times, 20.0 * np.log10(np.maximum(rms, 1e-8))


def _z(x: np.ndarray) -> np.ndarray:
    v = np.isfinite(x)
    if v.sum() < 2:
        return np.full(x.shape, np.nan)
    sd = float(np.std(x[v]))
    return (x - float(np.mean(x[v]))) / (sd if sd > 1e-9 else 1.0)


def word_prosody(words: pd.DataFrame, f0: GuardedF0 | None = None, energy=None) -> WordProsody:
    """Features of every word of ``words`` (DataFrame[start, end, word], sorted by start) from the
    guarded F0 track and an (times, dB) energy contour; either may be None (no audio)."""
    st = words["start"].to_numpy(np.float64)
    en = words["end"].to_numpy(np.float64)
    n = st.size
    f0_max, f0_low, f0_start, f0_end, e_max = (np.full(n, np.nan) for _ in range(5))
    if f0 is not None and np.isfinite(f0.median):
        semi = 12.0 * np.log2(np.where(np.isfinite(f0.f0), f0.f0, np.nan) / f0.median)
        a = np.searchsorted(f0.times, st, "left")
        b = np.searchsorted(f0.times, en, "right")
        for k in range(n):
            v = semi[a[k]:b[k]]
            v = v[np.isfinite(v)]
            if v.size:
                f0_max[k], f0_low[k] = float(v.max()), float(np.percentile(v, 10))
                q = max(1, int(0.3 * v.size))
                f0_start[k], f0_end[k] = float(np.median(v[:q])), float(np.median(v[-q:]))
    if energy is not None and len(energy[0]):
        et, edb = energy
        a = np.searchsorted(et, st, "left")
        b = np.searchsorted(et, en, "right")
        for k in range(n):
            if b[k] > a[k]:
                e_max[k] = float(edb[a[k]:b[k]].max())
    syl = np.array([syllables(w) for w in words["word"]], np.float64)
    dur = np.maximum(en - st, 1e-3)
    # a word of s syllables lasts about sqrt(s) times a one-syllable word (ours); the ratio is
    # relative to the speaker's geometric mean over all words
    ratio = dur / np.sqrt(syl)
    ratio = ratio / float(np.exp(np.mean(np.log(ratio)))) if n else ratio
    parts = [_z(f0_max), _z(f0_max), _z(e_max), _z(np.log(ratio))]
    stack = np.vstack(parts) if n else np.zeros((4, 0))
    with warnings.catch_warnings():  # a word without any feature gets prominence 0
        warnings.simplefilter("ignore", RuntimeWarning)
        prom = np.nanmean(stack, axis=0) if n else np.zeros(0)
    return WordProsody(f0_max, f0_low, f0_start, f0_end, e_max, ratio, np.nan_to_num(prom, nan=0.0))


# ---------------------------------------------------------------------------- segmentation
def log_prior(params: AnnotateParams, max_words: int) -> np.ndarray:
    """log P(n words), n = 0..max_words (index 0 unused): a log-normal with the configured mean and
    sd, discretized and normalized over 1..max_words."""
    m, s = float(params.clause_words_mean), float(params.clause_words_sd)
    sig2 = np.log1p((s / m) ** 2)
    mu = np.log(m) - sig2 / 2
    n = np.arange(1, max_words + 1, dtype=np.float64)
    lp = -np.log(n) - (np.log(n) - mu) ** 2 / (2 * sig2)
    lp -= np.log(np.exp(lp - lp.max()).sum()) + lp.max()
    return np.concatenate([[-np.inf], lp])


def boundary_evidence(words: pd.DataFrame, idx: np.ndarray, pros: WordProsody, params: AnnotateParams) -> np.ndarray:
    """Evidence (len(idx) - 1,) for a clause boundary after each word of the run ``idx`` (word
    indices into ``words``, in time order) except the last (module docstring), bias not included."""
    m = idx.size
    if m < 2:
        return np.zeros(0)
    st = words["start"].to_numpy(np.float64)[idx]
    en = words["end"].to_numpy(np.float64)[idx]
    toks = [str(w).lower().strip(".,;:!?\"") for w in words["word"].to_numpy()[idx]]
    gap = np.maximum(st[1:] - en[:-1], 0.0)
    ev = params.clause_w_pause * np.minimum(gap / max(params.max_gap, 1e-3), 1.0)
    f_end, f_start = pros.f0_end[idx], pros.f0_start[idx]
    for k in range(m - 1):
        after = f_start[k + 1:k + 3]
        after = after[np.isfinite(after)]
        if np.isfinite(f_end[k]) and after.size:
            reset = (float(after.min()) - f_end[k]) / params.clause_reset_semitones
            ev[k] += params.clause_w_reset * float(np.clip(reset, -1.0, 1.0))
        ev[k] += params.clause_w_lengthening * float(np.clip(np.log(pros.dur_ratio[idx[k]]) / np.log(1.5), -1, 1))
        if toks[k] in _PROCLITICS:
            ev[k] -= params.clause_w_function
    return ev


def split_run(evidence: np.ndarray, prominence: np.ndarray, durations: tuple | None, params: AnnotateParams,
              max_words: int) -> list[tuple[int, int]]:
    """Best segmentation of a run of m words into clauses [(i, j)] (word positions, j exclusive) by
    dynamic programming (module docstring). evidence: (m - 1,) boundary evidence without bias;
    prominence: (m,); durations: (starts (m,), ends (m,)) to honour ``max_clause_seconds``."""
    m = prominence.size
    lp = log_prior(params, max_words)
    best = np.full(m + 1, -np.inf)
    best[0] = 0.0
    back = np.zeros(m + 1, np.int64)
    for j in range(1, m + 1):
        for i in range(max(0, j - max_words), j):
            if not np.isfinite(best[i]):
                continue
            if durations is not None and params.max_clause_seconds and j - i > 1 \
                    and durations[1][j - 1] - durations[0][i] > params.max_clause_seconds:
                continue
            s = best[i] + clause_score(prominence[i:j], lp, params)
            if i > 0:
                s += evidence[i - 1] - params.clause_boundary_bias
            if s > best[j]:
                best[j], back[j] = s, i
    out, j = [], m
    while j > 0:
        out.append((int(back[j]), j))
        j = int(back[j])
    return out[::-1]


def clause_score(prominence: np.ndarray, lp: np.ndarray, params: AnnotateParams) -> float:
    """Score of one clause of words with these prominences: prior on its length and a penalty for a
    second strongly stressed word."""
    s = params.clause_prior_weight * float(lp[prominence.size])
    s -= params.clause_w_stress * max(0.0, params.clause_stress_z - float(prominence.max()))
    if prominence.size >= 2:
        second = float(np.partition(prominence, -2)[-2])
        s -= params.clause_w_stress * max(0.0, second - params.clause_stress_z)
    return s


def segmentation_score(cuts: list[tuple[int, int]], evidence: np.ndarray, prominence: np.ndarray,
                       params: AnnotateParams, max_words: int) -> float:
    """The objective ``split_run`` maximizes, for a given segmentation (tests compare the DP against
    every segmentation of a short run)."""
    lp = log_prior(params, max_words)
    s = 0.0
    for i, j in cuts:
        if j - i > max_words:
            return -np.inf
        s += clause_score(prominence[i:j], lp, params)
        if i > 0:
            s += evidence[i - 1] - params.clause_boundary_bias
    return s


def stressed_word(prominence: np.ndarray, idx) -> int:
    """Index (into the transcript) of the most prominent word among ``idx``."""
    idx = np.asarray(idx)
    return int(idx[int(np.argmax(prominence[idx]))])
