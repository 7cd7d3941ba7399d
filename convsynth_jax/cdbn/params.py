"""Parameters of the constrained DBN (Sadoughi & Busso, IEEE TAC): frozen dataclasses built once at
the task boundary from ``cfg.cdbn`` (:func:`cdbn_params_from_config`), and the model pytree.

Glossary (paper terms): *state* = the hidden state configuration node H_{m&s}; *constraint* = the
discrete parent of H (discourse function or prototypical gesture, Sec. VII-A); *stream* = the speech
(prosody, 6-D) or motion (head rotation, 3-D) observation node, each Gaussian given the state with a
full covariance, the two streams conditionally independent (block-diagonal joint covariance).
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import NamedTuple

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


@dataclass(frozen=True)
class CDBNParams:
    features: CDBNFeatureParams = field(default_factory=CDBNFeatureParams)
    train: TrainParams = field(default_factory=TrainParams)
    constrain: ConstrainParams = field(default_factory=ConstrainParams)
    synth: CDBNSynthParams = field(default_factory=CDBNSynthParams)
    jdbn_states: int = 7
    constraints: tuple = ("other", "nod", "shake")
    stream: str = "head"                     # head | hands (ours: which model system=cdbn trains)
    extra: dict = field(default_factory=dict)


POSTERIORS = ("smoother", "viterbi", "filter")
INITS = ("lbg", "random")
STREAMS = ("head", "hands")


def _build(cls, d: dict | None, where: str):
    d = dict(d or {})
    names = {f.name for f in fields(cls)}
    unknown = set(d) - names
    if unknown:
        raise ConfigError(f"{where}: unknown keys {sorted(unknown)}; expected {sorted(names)}")
    for k, v in list(d.items()):
        if isinstance(v, list):
            d[k] = tuple(v)
    return cls(**d)


def cdbn_params_from_config(c) -> CDBNParams:
    """``cfg.cdbn`` (a DictConfig or a plain mapping) -> CDBNParams, validated."""
    try:
        from omegaconf import DictConfig, OmegaConf

        if isinstance(c, DictConfig):
            c = OmegaConf.to_container(c, resolve=True)
    except ImportError:  # pragma: no cover
        pass
    c = dict(c or {})
    sub = {k: c.pop(k, None) for k in ("features", "train", "constrain", "synth")}
    p = CDBNParams(features=_build(CDBNFeatureParams, sub["features"], "cdbn.features"),
                   train=_build(TrainParams, sub["train"], "cdbn.train"),
                   constrain=_build(ConstrainParams, sub["constrain"], "cdbn.constrain"),
                   synth=_build(CDBNSynthParams, sub["synth"], "cdbn.synth"),
                   jdbn_states=int(c.pop("jdbn_states", 7)),
                   constraints=tuple(c.pop("constraints", ("other", "nod", "shake"))),
                   stream=str(c.pop("stream", "head")),
                   extra=c)
    if p.synth.posterior not in POSTERIORS:
        raise ConfigError(f"cdbn.synth.posterior must be one of {POSTERIORS}, got {p.synth.posterior!r}")
    if p.stream not in STREAMS:
        raise ConfigError(f"cdbn.stream must be one of {STREAMS}, got {p.stream!r}")
    if p.train.init not in INITS:
        raise ConfigError(f"cdbn.train.init must be one of {INITS}, got {p.train.init!r}")
    return p


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
