"""Word timings from speech: offline recognition (no transcript) and forced alignment of known text
(a transcript of phrases: subtitles, sentence intervals, Whisper segments without word timestamps).

Both use PocketSphinx (the ``pocketsphinx`` package) with the US English acoustic model, language
model and pronouncing dictionary that ship inside its wheel: nothing is downloaded at run time. The
recognizer's words are far from perfect (a word error rate of 25-40 % on conversational speech) but
its word *timings* are good where it recognizes a word (docs/converse.md gives the measured figures),
which is what the annotation of phonemic clauses needs; alignment of known text places words within
a few centiseconds.

Text is normalised for the dictionary: lower case, punctuation stripped, numbers spelled out
(``25`` -> twenty five), hyphenated and slashed compounds split; a word the dictionary lacks gets a
letter-by-letter pronunciation (so it still takes its time in the alignment). Audio at another sample
rate is resampled to the model's 16 kHz.
"""
from __future__ import annotations

import logging
import re
import time
from functools import lru_cache

import numpy as np
import pandas as pd

from ..errors import TranscriptFormatError

log = logging.getLogger(__name__)

MODEL_RATE = 16000
COLUMNS = ["start", "end", "word"]
# the default beams, then wider ones for a phrase the default cannot align
_BEAMS = ({}, {"beam": 1e-80, "wbeam": 1e-60, "pbeam": 1e-80, "lpbeam": 1e-60, "lponlybeam": 1e-60},
          {"beam": 1e-120, "wbeam": 1e-100, "pbeam": 1e-120, "lpbeam": 1e-100, "lponlybeam": 1e-100, "maxhmmpf": -1})
_FILLER = re.compile(r"^(<.*>|\[.*\]|\+\+.*\+\+)$")


def available() -> bool:
    try:
        import pocketsphinx  # noqa: F401
    except ImportError:
        return False
    return True


@lru_cache(maxsize=4)
def _decoder(align: bool = False, beams: int = 0):
    """A PocketSphinx decoder with the bundled US English model, for recognition (with the bundled
    language model) or for alignment of known text (none); loaded once per process (~0.2 s)."""
    try:
        from pocketsphinx import Decoder
    except ImportError as e:  # a core dependency: only a broken installation lands here
        raise TranscriptFormatError(f"speech recognition needs the pocketsphinx package ({e}): pip install pocketsphinx")
    # recognition: at most 3000 HMMs and 10 words per frame halve the time (8-9 s of CPU per 60 s of the
    # shared recordings instead of 15-20) at the same word error rate and timing accuracy
    extra = {"lm": None} if align else {"maxhmmpf": 3000, "maxwpf": 10}
    return Decoder(samprate=MODEL_RATE, loglevel="FATAL", **extra, **_BEAMS[beams])


def _pcm16(samples: np.ndarray, rate: int) -> np.ndarray:
    """Mono int16 samples at the model's rate."""
    x = np.asarray(samples, np.float64)
    if x.ndim == 2:
        x = x.mean(axis=1)
    if int(rate) != MODEL_RATE:
        from math import gcd

        from scipy.signal import resample_poly

        g = gcd(int(rate), MODEL_RATE)
        x = resample_poly(x, MODEL_RATE // g, int(rate) // g)
    return np.round(np.clip(x, -1.0, 1.0) * 32767).astype(np.int16)


def _segments(dec, pcm: np.ndarray) -> list[tuple[str, float, float]]:
    """(dictionary word, start s, end s) of one decoded utterance, fillers and silences left out."""
    dec.start_utt()
    dec.process_raw(pcm.tobytes(), no_search=False, full_utt=True)
    dec.end_utt()
    if dec.hyp() is None:
        return []
    frate = float(dec.config["frate"])
    out = []
    for s in dec.seg():
        if _FILLER.match(s.word):
            continue
        out.append((re.sub(r"\(\d+\)$", "", s.word), s.start_frame / frate, (s.end_frame + 1) / frate))
    return out


def recognize_words(samples: np.ndarray, rate: int, refine: bool = True) -> pd.DataFrame:
    """Words recognized in mono ``samples`` (float in [-1, 1]) at ``rate`` Hz: columns start, end,
    word (seconds). May be empty (the caller says what that means for its input). ``refine``: the
    timings from a forced alignment of the recognized words (:func:`_refine`)."""
    t0 = time.perf_counter()
    pcm = _pcm16(samples, rate)
    if not len(pcm) or int(np.abs(pcm.astype(np.int32)).max()) < 8:    # digital silence: the decoder would guess
        return pd.DataFrame(columns=COLUMNS).astype({"start": float, "end": float, "word": str})
    segs = _segments(_decoder(False), pcm)
    words = pd.DataFrame([(a, b, w) for w, a, b in segs], columns=COLUMNS)
    if refine and len(words) > 1:
        words = _refine(words, samples, rate)
    log.debug("recognized %d words in %.2f s of audio (%.2f s)", len(words), len(samples) / rate,
              time.perf_counter() - t0)
    return words


def _refine(words: pd.DataFrame, samples: np.ndarray, rate: int, gap_s: float = 0.3, longest_s: float = 8.0):
    """The recognized words' timings from a forced alignment of the recognized text, phrase by phrase
    (runs of words between pauses of ``gap_s``, at most ``longest_s``); a phrase the aligner cannot fit
    keeps the recognizer's timings. On the BEAT2 take this put 0.64 of the phonemic clauses'
    boundaries within 0.15 s of the word TextGrid's, against 0.56 with the recognizer's timings."""
    rows, groups = [], []
    for r in words.itertuples(index=False):
        if groups and r.start - rows[-1][1] < gap_s and r.end - rows[-1][0] <= longest_s:
            rows[-1] = [rows[-1][0], r.end, rows[-1][2] + " " + r.word]
            groups[-1].append((r.start, r.end, r.word))
        else:
            rows.append([r.start, r.end, r.word])
            groups.append([(r.start, r.end, r.word)])
    quiet = logging.getLogger(__name__)
    level = quiet.level
    quiet.setLevel(logging.ERROR)   # spelled words and retries of the recognizer's own text are no news
    try:
        return align_phrases(pd.DataFrame(rows, columns=COLUMNS), samples, rate, fallback=groups)
    finally:
        quiet.setLevel(level)


# ----------------------------------------------------------------------------------------------- text
_ONES = "zero one two three four five six seven eight nine ten eleven twelve thirteen fourteen fifteen sixteen " \
        "seventeen eighteen nineteen".split()
_TENS = "_ _ twenty thirty forty fifty sixty seventy eighty ninety".split()


def number_words(n: int) -> list[str]:
    """English words of a whole number 0 <= n < 10**12 (``1985`` -> one thousand nine hundred eighty five)."""
    if n < 20:
        return [_ONES[n]]
    if n < 100:
        return [_TENS[n // 10]] + ([_ONES[n % 10]] if n % 10 else [])
    if n < 1000:
        return [_ONES[n // 100], "hundred"] + (number_words(n % 100) if n % 100 else [])
    for size, name in ((10**9, "billion"), (10**6, "million"), (10**3, "thousand")):
        if n >= size:
            return number_words(n // size) + [name] + (number_words(n % size) if n % size else [])
    raise ValueError(n)


_LETTER_PHONES = {"a": "AE", "b": "B", "c": "K", "d": "D", "e": "EH", "f": "F", "g": "G", "h": "HH", "i": "IH",
                  "j": "JH", "k": "K", "l": "L", "m": "M", "n": "N", "o": "AA", "p": "P", "q": "K", "r": "R",
                  "s": "S", "t": "T", "u": "AH", "v": "V", "w": "W", "x": "K S", "y": "Y", "z": "Z"}


def _spell(word: str) -> str:
    """A rough pronunciation of a word the dictionary lacks, one phone per letter (doubled letters once)."""
    letters = re.sub(r"(.)\1+", r"\1", re.sub(r"[^a-z]", "", word))
    return " ".join(_LETTER_PHONES[c] for c in letters)


def normalise(token: str, dec) -> tuple[list[str], list[str]]:
    """(dictionary words, words given a spelled pronunciation) for one transcript token."""
    t = token.lower().replace("\u2019", "'").replace("\u2018", "'")
    t = re.sub(r"^[^\w']+|[^\w']+$", "", t).strip("'")
    if not t:
        return [], []
    if dec.lookup_word(t) is not None:
        return [t], []
    if re.fullmatch(r"\d+(\.\d+)?%?", t.replace(",", "")):
        num = t.replace(",", "").rstrip("%")
        whole, _, frac = num.partition(".")
        words = number_words(int(whole)) if len(whole) <= 12 else [_ONES[int(d)] for d in whole]
        if frac:
            words += ["point"] + [_ONES[int(d)] for d in frac]
        return words + (["percent"] if t.endswith("%") else []), []
    parts = [p for p in re.split(r"[-/_.]+|(?<=\D)(?=\d)|(?<=\d)(?=\D)", t) if p]
    if len(parts) > 1:
        out, spelled = [], []
        for p in parts:
            w, s = normalise(p, dec)
            out += w
            spelled += s
        return out, spelled
    bare = t.replace("'", "")
    if dec.lookup_word(bare) is not None:
        return [bare], []
    if not re.search(r"[a-z]", bare):
        return [], []
    if dec.lookup_word(bare) is None:
        dec.add_word(bare, _spell(bare), True)
    return [bare], [bare]


# ----------------------------------------------------------------------------------------------- alignment
def _align_text(pcm: np.ndarray, words: list[str], b: int) -> list[tuple[str, float, float]]:
    """Segments of ``words`` aligned to ``pcm`` with beam setting ``b``: all of them, or the words
    of the longest aligned beginning (the decoder's partial result when it cannot reach the end)."""
    dec = _decoder(True, b)
    for w in words:   # spelled words were added to the first decoder: add them to this one too
        if dec.lookup_word(w) is None:
            dec.add_word(w, _spell(w), True)
    try:
        dec.set_align_text(" ".join(words))
        segs = _segments(dec, pcm)
    except RuntimeError:
        return []
    k = 0
    while k < min(len(segs), len(words)) and segs[k][0] == words[k]:
        k += 1
    return segs[:k]


def _align_row(pcm: np.ndarray, words: list[str], end_s: float) -> tuple[list[tuple[str, float, float]] | None, int, int]:
    """(segments of all ``words`` in ``pcm``, or None; the widest beam setting used; how many words at
    the end were spread evenly instead of aligned). Where no beam setting reaches the end, the
    beginning that aligns is kept (less its last word, whose end the decoder stretches) and the rest
    aligned from there, as long as each round places a word; words the decoder never reaches (at most
    a third of the row) are spread evenly up to ``end_s`` (the row's end, seconds into ``pcm``)."""
    out, offset, rest, used = [], 0.0, list(words), 0
    while rest:
        best: list = []
        for b in range(len(_BEAMS)):
            segs = _align_text(pcm[int(round(offset * MODEL_RATE)):], rest, b)
            used = max(used, b)
            if len(segs) > len(best):
                best = segs
            if len(best) == len(rest):
                break
        if len(best) == len(rest):
            out += [(w, offset + a, offset + e) for w, a, e in best]
            return out, used, 0
        keep = best[:-1]
        if not keep:
            if 3 * len(rest) > len(words) or end_s - offset < 0.03 * len(rest):
                return None, used, 0
            edges = np.linspace(offset, end_s, len(rest) + 1)
            return out + [(w, float(a), float(e)) for w, a, e in zip(rest, edges[:-1], edges[1:])], used, len(rest)
        out += [(w, offset + a, offset + e) for w, a, e in keep]
        offset += keep[-1][2]
        rest = rest[len(keep):]
    return out, used, 0


def align_phrases(rows: pd.DataFrame, samples: np.ndarray, rate: int, path=None, pad_s: float = 0.3,
                  fallback: list | None = None) -> pd.DataFrame:
    """Word timings of a transcript whose rows may hold several words: each row holding more than one
    word is aligned against its stretch of the audio (widened by up to ``pad_s`` on each side, never
    past the middle of the gap to its neighbours); rows of one word are kept as they are. The words
    keep the transcript's spelling (a number spelled out for the alignment is one word again).
    A row that cannot be aligned raises :class:`TranscriptFormatError` naming it."""
    dec = _decoder(True, 0)
    pcm = _pcm16(samples, rate)
    total = len(pcm) / MODEL_RATE
    out, spelled_all = [], []
    starts, ends = rows["start"].to_numpy(float), rows["end"].to_numpy(float)
    for i, r in enumerate(rows.itertuples(index=False)):
        tokens = str(r.word).split()
        if len(tokens) <= 1:
            out.append((float(r.start), float(r.end), str(r.word)))
            continue
        groups, flat = [], []
        for tok in tokens:
            w, spelled = normalise(tok, dec)
            spelled_all += spelled
            groups.append((tok, len(flat), len(flat) + len(w)))
            flat += w
        if not flat:
            continue
        lo0 = max(0.0, r.start - pad_s if i == 0 else max(r.start - pad_s, (ends[i - 1] + r.start) / 2))
        hi0 = min(total, r.end + pad_s if i == len(rows) - 1 else min(r.end + pad_s, (r.end + starts[i + 1]) / 2))
        segs, b, spread = None, 0, 0
        # the row's own stretch, then widened into its neighbours (subtitles often cut a word's edge);
        # each with the default beams, then wider ones
        for widen in (0.0, 0.15, 0.3):
            lo, hi = max(0.0, min(lo0, r.start - widen)), min(total, max(hi0, r.end + widen))
            if hi > lo:
                segs, b, spread = _align_row(pcm[int(lo * MODEL_RATE):int(np.ceil(hi * MODEL_RATE))], flat,
                                             r.end - lo)
            if segs is not None:
                break
        if segs is None and fallback is not None:    # the caller's own timings of the row's words
            out += list(fallback[i])
            continue
        if segs is None:
            raise TranscriptFormatError(
                f"{r.start:.2f}-{r.end:.2f} s, {str(r.word)[:60]!r}: cannot be aligned to the audio "
                f"({lo:.2f}-{hi:.2f} s): check its times and words, or give word timings for it", path, f"row {i}")
        if spread:
            log.warning("%s: row %d (%.2f-%.2f s): the aligner did not reach its last %d word(s) (%s): spread evenly up "
                        "to the row's end", path or "", i, r.start, r.end, spread, " ".join(flat[-spread:]))
        if widen or b:
            log.info("%s: row %d (%.2f-%.2f s) aligned %s", path or "", i, r.start, r.end,
                     f"with {widen:g} s more audio each side" + (" and wider beams" if b else ""))
        for tok, a, e in groups:
            if e > a:
                out.append((lo + segs[a][1], lo + segs[e - 1][2], tok))
    if spelled_all:
        log.warning("%s: %d word(s) not in the pronouncing dictionary were aligned letter by letter: %s", path or "",
                    len(spelled_all), ", ".join(sorted(set(spelled_all))[:8]))
    # a row widened into its neighbour may place its first word over the neighbour's last: the rows'
    # order is the transcript's, so a word starts no earlier than the word before it ends
    fixed, t = [], 0.0
    for a, b, w in out:
        a = max(a, t)
        fixed.append((a, max(a, b), w))
        t = max(a, b)
    return pd.DataFrame(fixed, columns=COLUMNS)
