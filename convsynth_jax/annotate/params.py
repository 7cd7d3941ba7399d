"""Parameters of the annotation stage (paper Section 4.2 and Section 5); ``conf/annotate``."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional

from ..rig import DEFAULT_JOINTS


@dataclass(frozen=True)
class AnnotateParams:
    # Word corpus for listener responses (LR) and hesitation pauses (HP): None = the shipped
    # convsynth_jax/resources/word_corpus.yaml; a path to a YAML file with the keys listener_response
    # and hesitation; or those two lists inline. extra_words adds words to the chosen corpus.
    word_corpus: Any = None
    extra_words: Dict[str, List[str]] = field(
        default_factory=lambda: {"listener_response": [], "hesitation": []})
    max_gap: float = 0.3                       # s; a longer pause between words ends a phonemic clause
    # Words in context (docs/decisions.md#phonemic-clauses-from-prosody): a response word right after a word of one's own clause (within
    # max_gap) is part of that clause, not a listener response; a lexical filler (below; a word that
    # is also an ordinary word) is a hesitation only when a pause of filler_pause s or the end of the
    # turn follows it and it is no verb (not after a pronoun, "to" or an auxiliary). False = the
    # lists alone decide, word by word.
    word_context: bool = True
    filler_pause: float = 0.15                 # s (ours)
    lexical_fillers: List[str] = field(default_factory=lambda: ["like", "well", "you know"])
    max_clause_words: Optional[int] = None     # split longer clauses (None = no limit)
    max_clause_seconds: Optional[float] = None  # split clauses longer than this (None = no limit)
    # Phonemic clauses (annotate/clauses.py): "prosodic" (default; the paper's clause is a
    # group of words with one primary stress) splits every pause-delimited run of words by a dynamic
    # program over pauses, F0 resets, pre-boundary lengthening and stress, with a words-per-clause
    # prior; "pause" = clauses end at pauses > max_gap only (leaves a fluent sentence one clause).
    clause_method: str = "prosodic"
    clause_words_mean: float = 4.1             # prior mean (paper: 4.29 female, 3.86 male)
    clause_words_sd: float = 2.0               # prior sd (paper: 2.16, 1.36)
    clause_max_words: int = 12                 # hard limit of the prosodic method (ours)
    clause_prior_weight: float = 1.0           # weights of the DP objective (ours)
    clause_boundary_bias: float = 1.0          # cost of a boundary without evidence
    clause_w_pause: float = 2.0
    clause_w_reset: float = 5.0
    clause_reset_semitones: float = 2.0        # an F0 reset of this size counts fully
    clause_w_lengthening: float = 1.0
    clause_w_function: float = 1.0             # no boundary after "the", "of", "I", "and" ...
    clause_w_stress: float = 5.0               # penalty per z of a second stressed word
    clause_stress_z: float = 0.5               # prominence (z) above which a word is stressed
    # F0 for the peak indicator: praat (parselmouth) or opensmile (optional package, eGeMAPS F0)
    f0_backend: str = "praat"
    f0_range: str = "auto"                     # auto = speaker-adapted two-pass range; fixed = floor..ceiling
    f0_floor: float = 75.0
    f0_ceiling: float = 500.0
    f0_time_step: float = 0.01
    # Octave guard (annotate/clauses.py guard_f0): Praat's octave-jump cost (Praat's own
    # default 0.35), the speaker's range (median +- octaves over the whole recording), continuity
    # against a running median, and a median filter for peak picking
    f0_octave_jump_cost: float = 0.5
    f0_guard_octaves: float = 1.0
    f0_jump_semitones: float = 9.0
    # a frame at least this far from the speaker's median (semitones) and outside the speaker's own
    # range (the f0_range_quantile .. 1 - f0_range_quantile quantiles of the voiced frames) is an
    # octave error: a doubled or halved stretch too long for the running median to catch
    f0_near_octave_semitones: float = 10.0
    f0_range_quantile: float = 0.05
    f0_median_window: float = 0.25             # s
    f0_smooth_frames: int = 5
    # Motion segmentation: Eq. 1 (clip idle threshold) and Eq. 2 (window threshold)
    alpha_s: float = 0.1
    alpha_w: float = 0.1
    # Figure 3 trims a window against the movement found before it; True (ours) = where that
    # movement's speed really falls back to its theta_W (also after its window), False = the
    # paper's literal end inside its window
    extend_trim: bool = True
    up_axis: int = 1                           # vertical axis for nods (Y up)
    # Regexes (tried in order) naming the joints for hand and head speeds; None = the role's patterns
    # in convsynth_jax/rig.py
    joints: Dict[str, Any] = field(default_factory=lambda: {k: None for k in DEFAULT_JOINTS})
