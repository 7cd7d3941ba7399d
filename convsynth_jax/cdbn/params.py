"""Parameters of the constrained DBN (Sadoughi & Busso, IEEE TAC): frozen dataclasses built once at
the task boundary from the ``cdbn`` config group (``convsynth_jax.schema.build_params``), and the
model pytree.

Glossary (paper terms): *state* = the hidden state configuration node H_{m&s}; *constraint* = the
discrete parent of H (discourse function or prototypical gesture, Sec. VII-A); *stream* = the speech
(prosody, 6-D) or motion (head rotation, 3-D) observation node, each Gaussian given the state with a
full covariance, the two streams conditionally independent (block-diagonal joint covariance).
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any, Dict, NamedTuple, Optional

import numpy as np

from ..errors import ConfigError


class DBNModel(NamedTuple):
    """A (constrained) DBN. K states, C constraints (C = 1 for the jDBN baseline), D = speech + motion.

    means: (K, D); covariances: (K, D, D) block-diagonal over (speech, motion);
    initial: (C, K) P(q_1 = i | C_1 = c); transitions: (C, K, K) a^c_ij = P(q_t = j | q_{t-1} = i, C_t = c)
    (Eq. 5). Structural zeros of ``transitions``/``initial`` are exact zeros and stay zero under EM.
    speech_dims / motion_dims: column indices of each stream (static tuples);
    constraint_names: names of the C constraints; feature_layout: names of the D columns (checked
    when a model file is loaded against the features it is applied to).
    """

    means: np.ndarray
    covariances: np.ndarray
    initial: np.ndarray
    transitions: np.ndarray
    speech_dims: tuple
    motion_dims: tuple
    constraint_names: tuple
    feature_layout: tuple = ()

    @property
    def num_states(self) -> int:
        return int(self.means.shape[0])

    @property
    def num_constraints(self) -> int:
        return int(self.initial.shape[0])


@dataclass(frozen=True)
class CDBNFeatureParams:
    """Sec. IV-C. Prosody: F0 and energy + first and second derivatives (6-D) on 40 ms windows every
    ``hop`` s; unvoiced F0 interpolated; per-subject z-normalization. Motion: head rotation (3 DOF,
    degrees: pitch, yaw, roll of the head relative to the neck's parent chain)."""

    window: float = 0.040
    hop: float = 1.0 / 60.0
    f0_floor: float | str = "auto"        # Hz, or "auto": speaker-adaptive (two-pass, De Looze & Hirst)
    f0_ceiling: float = 600.0
    min_voiced_fraction: float = 0.10     # fewer voiced frames than this -> CDBNError (suggest a floor)
    # joints whose rotations compose the head rotation: roles of convsynth_jax.rig.RIG_JOINTS or names
    head_joints: tuple = ("neck", "head")
    fps: float = 30.0                     # model frame rate (motion and upsampled/downsampled speech)
    # hand stream (cdbn/hands.py): left upper arm, left forearm, right upper arm, right forearm, as
    # roles of convsynth_jax.rig.RIG_JOINTS (its "shoulder" role is the upper-arm joint) or joint
    # names ("|" = alternatives)
    arm_joints: tuple = ("left_shoulder", "left_elbow", "right_shoulder", "right_elbow")


@dataclass(frozen=True)
class TrainParams:
    """Sec. VI-C: LBG or random initialization, EM with a covariance floor and restarts."""

    init: str = "lbg"                 # lbg | random
    max_iter: int = 20
    tol: float = 1e-3                 # stop when the per-frame log-likelihood gains less than this
    restarts: int = 1                 # EM runs from different initializations; best log-likelihood kept
    covariance_floor: float = 1e-3    # minimum eigenvalue of each stream's covariance (z-units^2)
    lloyd_iter: int = 15              # Lloyd refinements after each LBG split
    lbg_epsilon: float = 0.1          # LBG split perturbation (data SDs)
    lbg_split: str = "greedy"         # greedy (split the worst codeword) | all (classic doubling)
    min_frames_per_state: int = 5     # fewer training frames than this per state -> CDBNError
    self_transition: float = 0.9      # initial self-transition probability
    seed: int = 0


@dataclass(frozen=True)
class ConstrainParams:
    """Sec. VII-B: N states per constraint, KL merge threshold, one shared state."""

    states_per_constraint: int = 4
    merge_threshold: float = 1.0
    shared_state: bool = True


@dataclass(frozen=True)
class CDBNSynthParams:
    """Sec. VI-B: posterior (smoother | viterbi | filter), key-point smoothing (15/s head)."""

    posterior: str = "smoother"
    keypoints_per_second: float = 15.0       # head (Sec. VI-B)
    hand_keypoints_per_second: float = 12.0  # hands (Sec. VI-B)
    # what the rest of the body does under the synthesized head (system=cdbn, head stream; the paper
    # leaves it to the renderer, Smartbody, which animates it): recording (an excerpt of one of the
    # character's training recordings, the head replaced; docs/cdbn.md) | mean (the character's mean
    # pose, still: the head point then lacks the body's share of the recordings' motion); the hand
    # stream keeps the mean pose
    body: str = "recording"
    # what is added to the key-point-smoothed expected value (Eq. 4 / 6): none (the paper) |
    # spectral (ours: the residual the means leave out, with the training clips' power spectrum;
    # cdbn/residual.py)
    residual: str = "none"
    # ours: lower the key-point rate below the paper's, down to 3/s, until the smoothed output's jerk on
    # the training clips is at most the recordings' (where the means jump between states faster than
    # the recordings move; systems/cdbn.py: match_keypoint_rate)
    match_jerk: bool = False


@dataclass(frozen=True)
class CDBNEvalParams:
    """``cdbn.eval``: the Sec. VIII protocol of ``task=cdbn_eval`` (cross-validation, grids, Eq. 8)."""

    folds: int = 10
    jdbn_grid: tuple = (4, 7, 10)
    cdbn_grid: tuple = (3, 4, 6)
    cca_slack: float = 0.01
    llr_slack: float = 0.01
    max_test_folds: Optional[int] = None  # evaluate only the first n test folds (None: all nine)
    fig6_states: int = 16
    seed: int = 0
    # Eq. 8 models are trained to convergence (the paper's EM is not cut at a fixed count): with the
    # cross-validation's max_iter = 20 the shared-state model's fast states are still moving and
    # its nod/shake distance was 0.13-0.18; converged 0.016 (README, "transition distance")
    distance_max_iter: int = 300
    distance_tol: float = 1e-4
    # ours (speed): the converged sparse CDBN of Eq. 8 continues EM from the cross-validation's CDBN
    # trained on the same turns with the same N (its per-constraint models, merges and first 20 EM
    # iterations are reused) instead of training it again from LBG
    distance_warm_start: bool = True
    hands: HandEvalParams = field(default_factory=lambda: HandEvalParams())


@dataclass(frozen=True)
class HandEvalParams:
    """``cdbn.eval.hands``: the hand model on real Bandai2 arm motion (Table V analogue, off while
    ``bvh_dir`` is None); ``eval``: CDBNEvalParams keys that differ for the hand model."""

    bvh_dir: Optional[str] = None
    wav: Optional[str] = None
    max_clips: Optional[int] = None
    gestures: str = "per_side"       # per_side: one constraint per gesture and side (the paper's one
    #                                  gesture per constraint); pooled (ours): raise / wave
    span: str = "motion"             # motion: the gesture spans the frames away from rest; fraction (ours):
    #                                  all but the clip's first and last 15%
    eval: Dict[str, Any] = field(default_factory=dict)

    def __post_init__(self):
        known = {f.name for f in fields(CDBNEvalParams)} - {"hands"}
        if self.gestures not in ("per_side", "pooled"):
            raise ConfigError(f"cdbn.eval.hands.gestures: 'per_side' or 'pooled', got {self.gestures!r}")
        if self.span not in ("motion", "fraction"):
            raise ConfigError(f"cdbn.eval.hands.span: 'motion' or 'fraction', got {self.span!r}")
        unknown = sorted(set(self.eval) - known)
        if unknown:
            raise ConfigError(f"cdbn.eval.hands.eval: unknown key(s) {unknown}; CDBNEvalParams has {sorted(known)}")


@dataclass(frozen=True)
class SemiSyntheticParams:
    """``cdbn.data``: the semi-synthetic nod/shake corpus (``cdbn/semisynthetic.py``)."""

    num_turns: int = 160
    turn_seconds: tuple = (5.0, 9.0)
    fps: float = 30.0
    sample_rate: int = 16000
    subjects: tuple = (("subject1", 120.0, 1.0), ("subject2", 205.0, 0.8))  # name, F0 (Hz), motion gain
    gestures_per_turn: tuple = (0, 2)      # inclusive range of gesture clauses per turn
    p_nod: float = 0.6                     # a gesture clause is a nod with this probability, else a shake
    nod_degrees: float = 9.0
    shake_degrees: float = 10.0
    pitch_gain: float = 4.5                # degrees per SD of the smoothed F0
    yaw_gain: float = 3.0                  # degrees per SD of the smoothed energy
    noise_degrees: float = 2.5
    seed: int = 0


POSTERIORS = ("smoother", "viterbi", "filter")
INITS = ("lbg", "random")
STREAMS = ("head", "hands")
BODIES = ("mean", "recording")
RESIDUALS = ("none", "spectral")


@dataclass(frozen=True)
class CDBNParams:
    """``conf/cdbn``: the model (features, training, constraints, synthesis) and the settings of the
    cdbn_* tasks (``corpus_root``, ``data``, ``eval``). Built by ``convsynth_jax.schema.build_params``."""

    features: CDBNFeatureParams = field(default_factory=CDBNFeatureParams)
    train: TrainParams = field(default_factory=TrainParams)
    constrain: ConstrainParams = field(default_factory=ConstrainParams)
    synth: CDBNSynthParams = field(default_factory=CDBNSynthParams)
    jdbn_states: int = 7
    constraints: tuple = ("other", "nod", "shake")
    stream: str = "head"                     # head | hands (ours: which model system=cdbn trains)
    corpus_root: Optional[str] = None        # the semi-synthetic corpus (None: <cache_dir>/cdbn_semisynthetic)
    data: SemiSyntheticParams = field(default_factory=SemiSyntheticParams)
    eval: CDBNEvalParams = field(default_factory=CDBNEvalParams)

    def __post_init__(self):
        if self.synth.posterior not in POSTERIORS:
            raise ConfigError(f"cdbn.synth.posterior must be one of {POSTERIORS}, got {self.synth.posterior!r}")
        if self.synth.body not in BODIES:
            raise ConfigError(f"cdbn.synth.body must be one of {BODIES}, got {self.synth.body!r}")
        if self.synth.residual not in RESIDUALS:
            raise ConfigError(f"cdbn.synth.residual must be one of {RESIDUALS}, got {self.synth.residual!r}")
        if self.stream not in STREAMS:
            raise ConfigError(f"cdbn.stream must be one of {STREAMS}, got {self.stream!r}")
        if self.train.init not in INITS:
            raise ConfigError(f"cdbn.train.init must be one of {INITS}, got {self.train.init!r}")


def num_parameters(num_states: int, speech_dim: int, motion_dim: int, transitions_mask=None,
                   initial_mask=None) -> int:
    """Free parameters of a DBN (Sec. VIII-A, Tables IV-V): per state a mean and a full covariance per
    stream, plus transition rows and the initial distribution (each row sums to one).

    Dense (jDBN): K (d_s + d_s(d_s+1)/2 + d_m + d_m(d_m+1)/2) + K(K-1) + (K-1); 7 head states -> 300,
    12 hand states (10-D arms) -> 1247. With masks (CDBN): each row of each constraint's transition
    matrix / initial vector contributes (allowed entries - 1).
    """
    per_state = speech_dim + speech_dim * (speech_dim + 1) // 2 + motion_dim + motion_dim * (motion_dim + 1) // 2
    n = num_states * per_state
    if transitions_mask is None:
        return n + num_states * (num_states - 1) + (num_states - 1)
    tm = np.asarray(transitions_mask, bool)
    im = np.asarray(initial_mask, bool)
    rows = tm.sum(-1)
    n += int(np.maximum(rows - 1, 0).sum())
    n += int(np.maximum(im.sum(-1) - 1, 0).sum())
    return n
