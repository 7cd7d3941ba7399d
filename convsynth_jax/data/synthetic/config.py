"""Parameters of the synthetic corpus: the defaults (``DEFAULTS``), their validation and the
parameter hash that keys the cache (``config_hash``), the characters' vocabulary and emotions."""
from __future__ import annotations

import dataclasses
import hashlib
import json
from dataclasses import dataclass, field
from typing import Dict, List

from ...errors import ConfigError
from ...schema import build_params

ROLES = ("main-agent", "interloctr")
EMOTIONS = {  # motion energy, speech rate
    "happy": (1.0, 1.0), "sad": (0.7, 0.85), "angry": (1.25, 1.1), "excited": (1.35, 1.2), "nervous": (0.85, 1.15),
}
VOCAB = ("we", "went", "there", "last", "summer", "and", "it", "was", "really", "nice", "you", "should",
         "have", "seen", "the", "place", "people", "were", "talking", "about", "work", "my", "friend",
         "said", "that", "would", "never", "happen", "again", "but", "then", "something", "changed",
         "school", "years", "ago", "remember", "when", "interview", "job", "money", "home", "city")
HESITATIONS = ("uh", "um", "er", "you know", "well")
RESPONSES = ("yeah", "uh-huh", "mm-hmm", "right", "I see", "wow", "okay")
# how the calibration may measure the realized rates (generator key calibrate_against; the measures
# themselves: calibration.CALIBRATION_MEASURES)
CALIBRATION_MEASURES = ("detector", "windows")


@dataclass(frozen=True)
class CharacterParams:
    """One role's character: name, clause length in words (mean, sd), voice F0 (Hz), body scale, and
    the co-occurrence rates planted (Table 1's hypotheses)."""

    name: str
    words_mean: float
    words_sd: float
    f0: float
    scale: float
    p_pc_lh: float
    p_pc_rh: float
    p_pc_either: float
    p_lr_nod: float
    p_ph_nod: float


@dataclass(frozen=True)
class GeneratorParams:
    """``corpus.generator``: every parameter of the synthetic corpus, with its default (the only one).
    :func:`generator_params` builds it from the keys a config changes."""

    seed: int = 0
    num_sessions: int = 17
    session_seconds: float = 106.0
    fps: int = 30
    sample_rate: int = 16000
    write_audio: bool = True
    characters: Dict[str, CharacterParams] = field(default_factory=lambda: {
        "main-agent": CharacterParams("female", 5.71, 2.48, 210.0, 0.94, 0.62, 0.65, 0.75, 0.58, 0.30),
        "interloctr": CharacterParams("male", 5.13, 1.56, 118.0, 1.0, 0.51, 0.50, 0.62, 0.53, 0.35),
    })
    clauses_per_turn: float = 3.0  # mean (1 + Poisson(mean - 1))
    p_hesitation: float = 0.6     # chance of a hesitation before each clause after the first in a turn
    p_listener_response: float = 0.45  # chance the listener responds after a clause end
    spontaneous_per_minute: float = 2.0  # gestures/nods per minute of time away from the own candidate windows
    # --- speech timing, calibrated against real speech as the annotation pipeline measures it
    # (experiments/bench/speech_timing.py, docs/synthetic_corpus.md; ours). The timing of generator
    # version 4 (uniform words of 0.20-0.34 s, clauses of 4.29 +- 2.16 / 3.86 +- 1.36 words, the paper's
    # counts, clause pauses of 0.45-0.8 s, p_hesitation 0.3) is conf/corpus/synthetic_v4_timing.yaml.
    # words_mean / words_sd are the paper's per-character counts times 1.33 / 1.15.
    word_seconds: List[float] = field(default_factory=lambda: [0.06, 1.0])  # range of word durations (before the emotion's speech rate)
    word_seconds_median: float = 0.235  # log-normal word durations with this median and log-sd, clipped to word_seconds;
    word_seconds_sigma: float = 0.45  # sigma 0: uniform on word_seconds
    word_gap: List[float] = field(default_factory=lambda: [0.03, 0.07])
    clause_tempo_sigma: float = 0.22  # log-sd of a per-clause tempo factor on its word durations (0: none)
    p_word_pause: float = 0.08    # chance that a word inside a clause is followed by a short pause (word_pause)
    word_pause: List[float] = field(default_factory=lambda: [0.15, 0.3])  # instead of a word_gap
    clause_pause: List[float] = field(default_factory=lambda: [0.15, 1.5])  # range of pauses after a paused clause and after a hesitation
    clause_pause_median: float = 0.45  # log-normal pauses with this median and log-sd, clipped to clause_pause;
    clause_pause_sigma: float = 0.6  # sigma 0: uniform on clause_pause
    min_clause_words: int = 2     # words per clause: round(Normal(words_mean, words_sd)) clipped to
    max_clause_words: int = 12    # min_clause_words..max_clause_words
    turn_gap: List[float] = field(default_factory=lambda: [0.5, 1.0])
    accent_rise: float = 0.28     # relative F0 rise of the pitch accent
    posture_sd: float = 1.5       # degrees: per-session posture offset of spine, neck, head and arms
    drift_sd: float = 1.5         # degrees: slow posture drift (about 10 s correlation time)
    min_event_gap: float = 0.3    # seconds of idle between consecutive events of the same head / of
                                  # the same hand when they are not coarticulated
    # --- difficulty knobs (what makes the corpus as hard as real data); each has an "off" value that
    # gives the easy corpus of generator version 2 in kind (not byte for byte)
    p_clause_pause: float = 0.3   # chance of a pause (clause_pause) between clauses of a turn; otherwise
                                  # the next clause follows after an ordinary word gap (off: 1.0)
    final_lengthening: float = 1.3  # the last word of a clause followed without pause is this much longer
                                  # (pre-boundary lengthening, a prosodic boundary cue; off: 1.0)
    p_backchannel_overlap: float = 0.5  # share of listener responses that start inside the speaker's clause,
                                  # 0.1-0.5 s before its end (overlapping speech; off: 0.0)
    p_turn_overlap: float = 0.3   # share of turn changes where the next speaker starts 0.1-0.6 s before
                                  # the previous one has finished (off: 0.0)
    coarticulation_gap: float = 0.8  # seconds: same-hand gestures whose idle gap would be shorter run into each
                                  # other: the first ends where the next starts and the hand is held, not
                                  # returned to rest, between the strokes (off: 0.0)
    # held level between coarticulated gestures (share of amplitude)
    coarticulation_hold: List[float] = field(default_factory=lambda: [0.4, 0.8])
    sensor_noise_deg: float = 0.08  # degrees: white measurement noise on every rotation channel (off: 0.03)
    sensor_noise_cm: float = 0.08  # cm: white measurement noise on the root position (off: 0.0)
    glitches_per_minute: float = 0.5  # marker-swap glitches per participant and minute (off: 0.0): for a few
                                  # frames the two arms swap (mirrored) or one joint jumps; listed in
                                  # glitches.csv, never in events.csv
    glitch_frames: List[int] = field(default_factory=lambda: [2, 5])  # glitch length in frames (inclusive range)
    posture_shift_sd: float = 3.7  # degrees: before each of its turns a participant shifts to a new rest
                                  # posture (offset of spine, neck, head and arms), away from its candidate
                                  # windows (off: 0.0)
    posture_shift_seconds: List[float] = field(default_factory=lambda: [0.6, 1.2])  # duration of a posture shift
    calibrate_rates: bool = True  # plant with p' such that the realized window rates (other movements landing
                                  # in windows, movements lost to neighbours) match the configured ones, p'
                                  # measured on the corpus's own plan (see planting_probabilities; off: False)
    calibrate_against: str = "detector"  # what measures the realized rates during calibration: "detector" (ours,
                                  # default) renders each pass's motion and counts with the annotation pipeline's
                                  # own speed detector and counter (stats.cooccurrence.hypothesis_matches on the
                                  # planted audio segments, default AnnotateParams), so Table 1 as the pipeline
                                  # measures it matches the configured rates; "windows" counts the planted
                                  # movement intervals with window_matches (no rendering, fast, but it treats a
                                  # movement that touches a window as used up to its end, which the detector
                                  # does not: it over-trims the next window, and a corpus calibrated that way
                                  # measures 5-11 points above the configured hand rates)
    calibration_passes: int = 5   # fixed-point passes of the calibration at most (the best one is kept)
    calibration_tolerance: float = 0.01  # stop the passes once every realized rate is this close to the configured one
    quota_planting: bool = True   # plant exactly round(p * N) caused movements over the corpus (spread over
                                  # the sessions in proportion) instead of N independent Bernoulli(p) draws,
                                  # so realized rates carry no sampling error (off: False)

    def __post_init__(self):
        if self.calibrate_against not in CALIBRATION_MEASURES:
            raise ConfigError(f"corpus.generator.calibrate_against: {self.calibrate_against!r}; expected one of "
                              f"{list(CALIBRATION_MEASURES)}")
        for role, c in self.characters.items():
            lh, rh, either = c.p_pc_lh, c.p_pc_rh, c.p_pc_either
            if not (max(lh, rh) <= either <= min(1.0, lh + rh)):
                raise ConfigError(f"characters.{role}: need max(p_pc_lh, p_pc_rh) <= p_pc_either <= p_pc_lh + p_pc_rh")
        if self.num_sessions < 1 or self.session_seconds < 10:
            raise ConfigError("need at least one session of at least 10 s")


# the defaults as the plain dict the generator reads (resolve_config)
DEFAULTS: dict = dataclasses.asdict(GeneratorParams())

# bumped whenever the generator's output changes for the same parameters (part of the parameter hash)
GENERATOR_VERSION = 5


def generator_params(config=None) -> GeneratorParams:
    """The typed generator parameters: the defaults with the keys of ``config`` (a plain mapping,
    e.g. ``corpus.generator``) changed; a character given partly keeps its other defaults."""
    return build_params(GeneratorParams, config, "corpus.generator")


def resolve_config(config=None) -> dict:
    """:func:`generator_params` as the plain dict the generator reads and hashes (``config_hash``)."""
    return dataclasses.asdict(generator_params(config))


def config_hash(cfg: dict) -> str:
    """Hash of the resolved parameters and the generator version (a cached corpus is reused only if
    it matches)."""
    blob = {"generator_version": GENERATOR_VERSION, "config": cfg}
    if cfg.get("calibrate_rates") and cfg.get("calibrate_against") == "detector":
        blob["detector"] = detector_settings()  # the corpus depends on the detector it was calibrated with
    blob = json.dumps(blob, sort_keys=True)
    return hashlib.sha1(blob.encode()).hexdigest()[:16]



def detector_settings() -> dict:
    """The annotation settings the ``detector`` calibration counts with (``AnnotateParams`` defaults:
    the paper's Eq. 1-2 and the pipeline's window trimming); part of the corpus parameter hash."""
    from ...annotate.params import AnnotateParams

    ap = AnnotateParams()
    return {"alpha_s": float(ap.alpha_s), "alpha_w": float(ap.alpha_w), "extend_trim": bool(ap.extend_trim),
            "up_axis": int(ap.up_axis)}
