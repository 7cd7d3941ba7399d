"""Synthetic dyadic conversation corpus: the embedded default dataset.

Writes the same files a real corpus has (GENEA 2023 dyadic layout) plus the planted ground truth:

* ``<session>_main-agent.{bvh,wav,tsv}`` and ``<session>_interloctr.{bvh,wav,tsv}``;
* ``events.csv`` (session, participant, kind, start, peak, end) with every planted audio segment
  (PC, LR, HP) and motion event (LH, RH, Nod; a two-handed gesture is one LH and one RH row);
* ``glitches.csv`` (session, participant, kind, joint, channel, degrees, start_frame, end_frame) with
  every motion-capture glitch put into the BVH;
* ``corpus.json`` with the generator parameters, their hash, the characters and the calibration report.

The process: turn-taking between two seated people; a turn is a run of phonemic clauses (words per
clause drawn around each character's mean and spread; word durations, per-clause tempo and pauses
calibrated so that the annotation pipeline measures the clause durations of real speech, see
docs/synthetic_corpus.md), mostly joined without a pause (fluent
stretches whose clause boundaries show only as an F0 reset and pre-boundary lengthening), with
hesitations inside turns; the listener gives listener responses near clause ends, often over the end
of the clause, and turns may overlap. Audio is a harmonic voice through two formant resonators with an
F0 contour per clause (declination plus a pitch accent on the stressed word, which is the clause's
F0 peak). Motion is idle (breathing, slow drift, small noise) plus hand gestures (preparation,
stroke near the F0 peak, retraction; close same-hand gestures coarticulated, without rest between
them) and nods, planted so that the realized co-occurrence rates in the paper's windows match the
configured probabilities (default: the paper's Table 1; see ``planting_probabilities``), a small
spontaneous rate away from the windows, per-turn posture shifts, sensor noise and a few marker-swap
glitches (``glitches.csv``). Every difficulty has a parameter in ``DEFAULTS`` with an "off" value
(``conf/corpus/synthetic_tiny.yaml`` turns them all off).

Modules: ``config`` (defaults, validation, hash), ``conversation`` (turns, clauses, responses),
``voice`` (audio), ``planting`` (which movements, when), ``motion`` (rendering a participant's
motion), ``plan`` (one session's plan), ``calibration`` (planting probabilities), ``writer`` (files
and the cache).
"""
from .calibration import (CALIBRATION_MEASURES, CORE, HYPOTHESIS_KEYS, planting_probabilities,  # noqa: F401
                          window_matches)
from .config import (DEFAULTS, EMOTIONS, GENERATOR_VERSION, HESITATIONS, RESPONSES, ROLES, VOCAB,  # noqa: F401
                     config_hash, detector_settings, resolve_config)
from .conversation import SAME_SPEAKER_GAP, Segment, _conversation, _session_start  # noqa: F401
from .motion import _motion, _smooth_noise, _zxy_deg_to_quat  # noqa: F401
from .plan import _plan, _quota_offsets, _render_motion, _render_rng  # noqa: F401
from .voice import _render_voice  # noqa: F401
from .writer import GLITCH_COLUMNS, ensure_synthetic_corpus, make_synthetic_corpus  # noqa: F401
