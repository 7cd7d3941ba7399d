"""The constrained DBN (Sadoughi & Busso) as a synthesis system of the framework (``system=cdbn``).

fit: head rotation (composed Neck/Head rotations) of the character's training clips and prosody
from each clip's own audio channel (``clip.audio_path``/``clip.audio_channel`` as the annotation
records carry them, or an ``Audio`` in ``clip.audio``), both z-normalized over the character's
training data; constraints = the own-channel audio label per frame (idle / PC / LR / HP, the
framework's annotation; a coarser mapping can be set in ``options.constraint_map``). Condition
``cdbn`` trains the constrained model (N states per constraint, fewer for a constraint with little
data: at most frames / (4 * min_frames_per_state)), condition ``jdbn`` the baseline.
synthesize: prosody of ``window.own_audio`` normalized with the character's training statistics,
state posteriors under the window's own labels, motion = sum_i gamma_i mu_i (Eq. 4/6), key-point
slerp smoothing; ours (``cdbn.synth.residual=spectral``, ``preset=quality``): plus a draw of the
residual the smoothed means lack against the training recordings' spectrum (``cdbn/residual.py``,
fitted on the training clips). The rest of the body (the paper leaves it to its renderer) plays an
excerpt of one of the character's training recordings (drawn with the window's seed) whose head is
replaced by the synthesized one (``cdbn.synth.body=recording``, default), or holds the training mean
pose (``cdbn.synth.body=mean``). Head only: produces_hands False.

``cdbn.stream`` (ours; ``system.options.stream=hands``) selects the model: ``head`` (default, 3 DOF
head rotation, 15 key points/s) or ``hands`` (the paper's separate hand model: arm 3 DOF x 2 and
forearm 2 DOF x 2 of cdbn/hands.py, 12 key points/s; the head then holds the mean pose and the
system reports produces_hands True).

Parameters: ``params`` is the run's :class:`~convsynth_jax.params.Params` (its ``cdbn`` group), a
:class:`~convsynth_jax.cdbn.params.CDBNParams`, or None (defaults); ``system.options`` entries
override ``cdbn`` keys.
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from typing import Optional

import numpy as np

from ..cdbn.cdbn import TrainedModel, train_cdbn, train_jdbn
from ..cdbn.features import (
    FEATURE_LAYOUT,
    SPEECH_NAMES,
    Normalization,
    head_euler_to_quat,
    head_rotation,
    head_rotation_from_quat,
    speech_features,
)
from ..cdbn.hands import (
    HAND_NAMES,
    arm_angles,
    arm_quaternions,
    arm_rig,
    arms_into_motion,
    keypoint_smooth_joints,
    smooth_arm_angles,
)
from ..cdbn.params import CDBNParams
from ..cdbn.residual import draw_residual, fit_residual_spectrum
from ..cdbn.synthesize import (
    body_excerpt,
    expected_motion,
    head_into_motion,
    head_onto_body,
    keypoint_smooth,
    state_posteriors,
    state_posteriors_batch,
    synthesize_head,
)
from ..annotate.kinds import AUDIO_LABEL_NAMES
from ..errors import CDBNError
from ..kinematics import jerk
from ..schema import build_params
from .base import SynthesisSystem, WindowInput, WindowResult

log = logging.getLogger(__name__)



@dataclass
class CDBNFit:
    trained: TrainedModel
    speech_norm: Normalization
    motion_norm: Normalization
    template: object            # a training Motion (skeleton and mean pose of the output)
    constrained: bool
    constraint_map: tuple       # audio label code -> constraint code
    seconds: float
    stream: str = "head"        # head | hands
    rig: object = None          # hands: the ArmRig of the template's skeleton
    bodies: tuple = ()          # cdbn.synth.body=recording: the character's training motions
    residual: object = None     # cdbn.synth.residual=spectral: the ResidualSpectrum of the training clips
    keypoints_per_second: float | None = None  # the rate synthesis smooths with (None: the configured one)


def _params(params, options: dict) -> CDBNParams:
    """The run's CDBN parameters (``params.cdbn`` of a :class:`~convsynth_jax.params.Params`, a
    CDBNParams, or the defaults for None) with ``system.options`` merged onto them; ``constraint_map``
    is an option of the system itself."""
    base = params if isinstance(params, CDBNParams) else getattr(params, "cdbn", None)
    if params is not None and not isinstance(base, CDBNParams):
        raise CDBNError(f"system cdbn needs Params with a cdbn group or CDBNParams, got {type(params).__name__}")
    opts = {k: v for k, v in (options or {}).items() if k != "constraint_map"}
    return build_params(CDBNParams, opts, "system.options", base=base)


RATE_LADDER = (15.0, 12.0, 10.0, 7.5, 6.0, 5.0, 4.0, 3.0)


def _angular_jerk(x: np.ndarray, fps: float) -> float:
    """Mean norm of the angles' jerk (``kinematics.jerk``, the project's one definition); 0 under 4 frames."""
    j = jerk(np.asarray(x, np.float64), fps)
    return float(np.linalg.norm(j, axis=1).mean()) if len(j) else 0.0


def match_keypoint_rate(recordings: list, means: list, fps: float, rate: float, smooth) -> float:
    """Ours (``cdbn.synth.match_jerk``): the highest key-point rate, from ``rate`` (the paper's) down
    the ladder 15, 12, 10, 7.5, 6, 5, 4, 3 per second, at which the smoothed output (``smooth(means_i,
    rate)``) has at most the recordings' mean jerk over the training clips (frame-weighted); the
    lowest rate where none has. The paper's rate stays where its output is not jerkier than the
    recordings."""
    frames = np.array([len(r) for r in recordings], float)
    target = float(np.dot(frames, [_angular_jerk(r, fps) for r in recordings]) / frames.sum())
    ladder = [rate] + [r for r in RATE_LADDER if r < rate]
    for r in ladder:
        out = float(np.dot(frames, [_angular_jerk(smooth(m, r), fps) for m in means]) / frames.sum())
        if out <= target:
            return float(r)
    return float(ladder[-1])


def _audio_of(clip):
    from ..io.audio import Audio, load_audio

    a = getattr(clip, "audio", None)
    if isinstance(a, Audio):
        return a
    path = getattr(clip, "audio_path", None)
    if path:
        return load_audio(path, channel=getattr(clip, "audio_channel", None))
    raise CDBNError(f"system cdbn needs the clip's audio (clip.audio_path or clip.audio) for "
                    f"{getattr(clip, 'session', '?')}/{getattr(clip, 'role', '?')}")


@dataclass(frozen=True)
class CDBNCondition:
    """A condition of ``system=cdbn`` (``conf/system/cdbn.yaml``): the constrained DBN (Chiu & Marsella
    2011) or the unconstrained joint DBN; None: constrained for the condition named ``cdbn``."""

    constrained: Optional[bool] = None


class CDBNSystem(SynthesisSystem):
    produces_hands = False
    needs_audio = True
    condition_type = CDBNCondition

    def __init__(self, params, system):
        super().__init__(params, system)
        self.cdbn = _params(params, dict(system.options or {}))
        cmap = (system.options or {}).get("constraint_map") or {}
        labels = tuple(AUDIO_LABEL_NAMES[c] for c in sorted(AUDIO_LABEL_NAMES))   # the registry's, by code
        self.constraint_names = tuple(dict.fromkeys(cmap.get(n, n) for n in labels))
        self.constraint_map = tuple(self.constraint_names.index(cmap.get(n, n)) for n in labels)
        self.stream = self.cdbn.stream
        self.produces_hands = self.stream == "hands"

    def fit_key(self, condition: str):
        return condition

    def _constrained(self, condition: str) -> bool:
        return bool(self.condition_options(condition).get("constrained", condition == "cdbn"))

    def fit(self, clips, character, condition, cache_dir=None) -> CDBNFit:
        t0 = time.perf_counter()
        constrained = self._constrained(condition)
        fp = self.cdbn.features
        speech, motion, codes = [], [], []
        mine = [c for c in clips if getattr(c, "character", character) == character]
        if not mine:
            raise CDBNError(f"no training clips of character {character!r}")
        hands = self.stream == "hands"
        rig = arm_rig(mine[0].motion.skeleton, fp) if hands else None
        for clip in mine:
            m = arm_angles(clip.motion, fp, rig) if hands else head_rotation(clip.motion, fp)
            s = speech_features(_audio_of(clip), fp, len(m), clip.motion.fps,
                                path=getattr(clip, "audio_path", None) or clip.session)
            lab = np.asarray(getattr(clip.own, "label", clip.own), np.int64)[: len(m)]
            speech.append(s)
            motion.append(m)
            codes.append(np.asarray(self.constraint_map, np.int32)[lab])
        sn = Normalization.fit(np.concatenate(speech))
        mn = Normalization.fit(np.concatenate(motion))
        seqs = [np.concatenate([sn.apply(s), mn.apply(m)], axis=1) for s, m in zip(speech, motion)]
        layout = SPEECH_NAMES + HAND_NAMES if hands else FEATURE_LAYOUT
        sd, md = tuple(range(6)), tuple(range(6, len(layout)))
        tp = self.cdbn.train
        if constrained:
            counts = np.bincount(np.concatenate(codes), minlength=len(self.constraint_names))
            N = self.cdbn.constrain.states_per_constraint
            Ns = tuple(int(max(1, min(N, c // (4 * tp.min_frames_per_state)))) for c in counts)
            if min(counts) < tp.min_frames_per_state:
                missing = [n for n, c in zip(self.constraint_names, counts) if c < tp.min_frames_per_state]
                raise CDBNError(f"character {character!r}: too few training frames for constraints {missing} "
                                f"(counts {dict(zip(self.constraint_names, counts.tolist()))}); map them onto "
                                "others with system.options.constraint_map")
            tm = train_cdbn(seqs, codes, Ns, sd, md, tp, self.constraint_names, self.cdbn.constrain.merge_threshold,
                            self.cdbn.constrain.shared_state, layout)
        else:
            tm = train_jdbn(seqs, self.cdbn.jdbn_states, sd, md, tp, layout)
        bodies = tuple(c.motion for c in mine) if self.cdbn.synth.body == "recording" and not hands else ()
        residual, rate = None, self._rate(rig)
        sp = self.cdbn.synth
        if sp.residual == "spectral" or sp.match_jerk:   # ours: this model's own output on the training speech
            gammas = state_posteriors_batch(tm.model, [sn.apply(s) for s in speech], codes if constrained else None,
                                            sp.posterior)
            fps = float(mine[0].motion.fps)
            means = [mn.invert(expected_motion(tm.model, g)) for g in gammas]
            if sp.match_jerk:
                rate = match_keypoint_rate(motion, means, fps, rate, lambda a, r: self._smoothed(a, fps, rig, r))
                log.info("cdbn %s/%s: %g key points per second (the recordings' jerk on the training clips)",
                         character, condition, rate)
            if sp.residual == "spectral":
                residual = fit_residual_spectrum(motion, [self._smoothed(m, fps, rig, rate) for m in means], fps)
        return CDBNFit(tm, sn, mn, mine[0].motion, constrained, self.constraint_map, time.perf_counter() - t0,
                       self.stream, rig, bodies, residual, rate)

    def _rate(self, rig) -> float:
        """The configured key-point rate of the stream (Sec. VI-B: 15/s head, 12/s hands)."""
        sp = self.cdbn.synth
        return sp.hand_keypoints_per_second if rig is not None else sp.keypoints_per_second

    def _smoothed(self, angles: np.ndarray, fps: float, rig, rate: float) -> np.ndarray:
        """The features after the paper's key-point smoothing (Sec. VI-B) at ``rate``, in feature space."""
        if rig is not None:
            return smooth_arm_angles(angles, rig, fps, rate)
        return head_rotation_from_quat(keypoint_smooth(angles, fps, rate))

    def synthesize(self, model: CDBNFit, window: WindowInput, condition: str) -> WindowResult:
        t0 = time.perf_counter()
        n = int(window.num_frames)
        audio = window.own_audio
        if audio is None:
            return WindowResult(False, failure="system cdbn needs the window's own audio (own_audio is None)")
        try:
            raw = speech_features(audio, self.cdbn.features, n, window.fps, path=f"{window.session}/{window.role}")
        except CDBNError as e:
            return WindowResult(False, failure=str(e), seconds=time.perf_counter() - t0)
        cons = None
        if model.constrained:
            lab = np.asarray(getattr(window.own_frames, "label", window.own_frames), np.int64)
            if lab.ndim != 1 or len(lab) != n:
                lab = np.zeros(n, np.int64)
            cons = np.asarray(model.constraint_map, np.int32)[lab]
        name = f"cdbn:{window.session}:{window.role}"
        rate = model.keypoints_per_second or self._rate(model.rig)
        if model.stream == "hands":
            gamma = state_posteriors(model.trained.model, model.speech_norm.apply(raw), cons, self.cdbn.synth.posterior)
            angles = model.motion_norm.invert(expected_motion(model.trained.model, gamma))
            if model.residual is not None:   # ours: the smoothed means plus the spectral residual
                angles = self._smoothed(angles, window.fps, model.rig, rate) + self._residual(model, n, window.seed)
                q = arm_quaternions(angles, model.rig)
            else:
                q = keypoint_smooth_joints(arm_quaternions(angles, model.rig), window.fps, rate)
            motion = arms_into_motion(model.template, q, model.rig, name)
        else:
            angles, gamma = synthesize_head(model.trained.model, model.speech_norm.apply(raw), cons,
                                            self.cdbn.synth.posterior, model.motion_norm.mean, model.motion_norm.sd)
            q = keypoint_smooth(angles, window.fps, rate)
            if model.residual is not None:   # ours: the smoothed means plus the spectral residual
                q = head_euler_to_quat(head_rotation_from_quat(q) + self._residual(model, n, window.seed))
            if model.bodies:   # ours (cdbn.synth.body=recording): the head on a training recording's body
                body = body_excerpt(list(model.bodies), n, np.random.default_rng(window.seed))
                motion = head_onto_body(body, q, self.cdbn.features.head_joints, name)
            else:
                motion = head_into_motion(model.template, q, self.cdbn.features.head_joints, name)
        ent = -np.sum(gamma * np.log(np.maximum(gamma, 1e-12)), axis=1)
        return WindowResult(True, motion=motion, seconds=time.perf_counter() - t0,
                            diagnostics={"states": model.trained.model.num_states,
                                         "posterior_entropy": float(ent.mean())})

    @staticmethod
    def _residual(model: CDBNFit, n: int, seed) -> np.ndarray:
        """(n, d) degrees: a draw of the spectral residual, from the window's seed (its own stream, apart
        from the body excerpt's)."""
        return draw_residual(model.residual, n, np.random.default_rng([int(seed or 0), 1]))
