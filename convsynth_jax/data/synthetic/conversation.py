"""The conversation of one session: turns of phonemic clauses, hesitations, listener responses and
overlaps of two participants (audio segments with word timings; nothing is rendered here)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .config import EMOTIONS, HESITATIONS, RESPONSES, ROLES, VOCAB


@dataclass
class Segment:
    role: str
    kind: str  # PC, LR, HP
    start: float
    end: float
    peak: float
    words: list  # (start, end, word, stressed)


def _conversation(rng: np.random.Generator, cfg: dict, duration: float, rate: float) -> list[Segment]:
    """Audio segments of both participants for one session.

    Turns alternate; a turn is a run of clauses, mostly joined without a pause (``p_clause_pause``),
    so a pause-free stretch holds several clauses whose boundaries show only in the prosody (F0 reset,
    pre-boundary lengthening). Listener responses may start inside the speaker's clause
    (``p_backchannel_overlap``) and the next turn may start before the previous one has ended
    (``p_turn_overlap``). One participant's own segments never overlap each other: a new segment of a
    participant starts at least ``SAME_SPEAKER_GAP`` after that participant's previous one.
    Speech timing (ours, calibrated against real speech): word durations and pauses log-normal
    (``_duration``), a per-clause tempo factor, short pauses inside clauses; each draws nothing
    when off (sigma or probability 0), which gives the timing of generator version 4."""
    u = lambda lo_hi: rng.uniform(*lo_hi)  # noqa: E731
    word_seconds = lambda: _duration(rng, cfg["word_seconds"], cfg["word_seconds_median"], cfg["word_seconds_sigma"])  # noqa: E731
    pause_after = lambda: _duration(rng, cfg["clause_pause"], cfg["clause_pause_median"],  # noqa: E731
                                    cfg["clause_pause_sigma"])
    segs: list[Segment] = []
    busy = {r: -1.0 for r in ROLES}  # end of each participant's latest segment
    t = rng.uniform(0.5, 1.5)
    speaker = int(rng.integers(2))
    end_limit = duration - 1.5
    lengthen = float(cfg["final_lengthening"])
    stop = False
    while t < end_limit and not stop:
        role, other = ROLES[speaker], ROLES[1 - speaker]
        ch = cfg["characters"][role]
        n_clauses = 1 + rng.poisson(max(cfg["clauses_per_turn"] - 1, 0))
        for c in range(n_clauses):
            if c > 0 and rng.random() < cfg["p_hesitation"]:
                word = HESITATIONS[rng.integers(len(HESITATIONS))]
                d = rng.uniform(0.3, 0.5) / rate
                if t + d > end_limit:
                    stop = True
                    break
                segs.append(Segment(role, "HP", t, t + d, t + d / 2, [(t, t + d, word, False)]))
                busy[role] = t + d
                t += d + pause_after() / rate  # a filler is followed by a pause
            n_words = int(np.clip(np.round(rng.normal(ch["words_mean"], ch["words_sd"])), cfg["min_clause_words"],
                                  cfg["max_clause_words"]))
            last = c == n_clauses - 1
            fluent = not last and rng.random() >= cfg["p_clause_pause"]
            words = []
            w0 = t
            # the clause's own tempo (people speed up and slow down from phrase to phrase)
            tempo = np.exp(rng.normal(0.0, cfg["clause_tempo_sigma"])) if cfg["clause_tempo_sigma"] > 0 else 1.0
            for i in range(n_words):
                d = word_seconds() * tempo / rate
                if fluent and i == n_words - 1:
                    d *= lengthen
                words.append([t, t + d, VOCAB[rng.integers(len(VOCAB))], False])
                if cfg["p_word_pause"] > 0 and i < n_words - 1 and rng.random() < cfg["p_word_pause"]:
                    t += d + u(cfg["word_pause"])  # a short pause inside the clause
                else:
                    t += d + u(cfg["word_gap"])
            t -= words and (t - words[-1][1])  # no gap after the last word
            if t > end_limit:
                stop = True
                break
            k = int(rng.integers(n_words))
            words[k][3] = True
            peak = 0.5 * (words[k][0] + words[k][1])
            segs.append(Segment(role, "PC", w0, t, peak, [tuple(w) for w in words]))
            busy[role] = t
            pause = pause_after() / rate if not fluent else u(cfg["word_gap"])
            if rng.random() < cfg["p_listener_response"]:
                d = rng.uniform(0.3, 0.55)
                if rng.random() < cfg["p_backchannel_overlap"]:  # over the end of the clause
                    ls = max(t - rng.uniform(0.1, 0.5), w0 + 0.1)
                else:
                    ls = t + rng.uniform(0.05, 0.25)
                ls = max(ls, busy[other] + SAME_SPEAKER_GAP)
                word = RESPONSES[rng.integers(len(RESPONSES))]
                segs.append(Segment(other, "LR", ls, ls + d, ls + d / 2, [(ls, ls + d, word, False)]))
                busy[other] = ls + d
                if not fluent:  # a paused speaker waits for the response to end
                    pause = max(pause, ls + d + 0.4 - t)
            t += pause
        # the next speaker: after a gap, or (p_turn_overlap) before the current speaker has finished
        turn_end = busy[role]
        if rng.random() < cfg["p_turn_overlap"]:
            t_next = turn_end - rng.uniform(0.1, 0.6)
        else:
            t_next = turn_end + u(cfg["turn_gap"])
        speaker = 1 - speaker
        t = max(t_next, busy[ROLES[speaker]] + SAME_SPEAKER_GAP)
    segs.sort(key=lambda s: (s.start, s.role))
    return segs


def _duration(rng: np.random.Generator, bounds, median: float, sigma: float) -> float:
    """A duration in seconds: uniform on ``bounds`` if ``sigma`` is 0, else log-normal with this
    ``median`` and log-sd ``sigma``, clipped to ``bounds``; one draw from ``rng`` either way."""
    if sigma <= 0:
        return rng.uniform(*bounds)
    return float(np.clip(np.exp(rng.normal(np.log(median), sigma)), *bounds))


SAME_SPEAKER_GAP = 0.35  # seconds between consecutive segments of one participant (at least)


def _session_start(idx: int, cfg: dict):
    """(generator, emotion, conversation) of session ``idx``."""
    rng = np.random.default_rng([int(cfg["seed"]), idx])
    emotion = list(EMOTIONS)[int(rng.integers(len(EMOTIONS)))]
    segs = _conversation(rng, cfg, float(cfg["session_seconds"]), EMOTIONS[emotion][1])
    return rng, emotion, segs


def _turn_starts(segs: list[Segment], role: str) -> list[float]:
    """Start times of ``role``'s turns: its clauses that follow a clause of the other participant."""
    out, last = [], None
    for s in segs:  # sorted by start
        if s.kind != "PC":
            continue
        if s.role == role and last is not None and last != role:
            out.append(s.start)
        last = s.role
    return out
