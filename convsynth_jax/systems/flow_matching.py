"""A learned peer on the leaderboard (ours, not the paper's): conditional flow matching from the
speaker's and the partner's audio to the character's body motion (``system=flow_matching``;
the model: ``convsynth_jax/flow/``).

fit: the character's training recordings resampled to the model's rate (``options.fps``), encoded
(6-D joint rotations and root motion, ``flow/features.py``), z-normalised; audio features of each
recording's own channel and its partner's; a velocity field trained on them (seeded). The trained
model is cached in ``<cache_dir>/flow_matching/`` under a key over the training arrays, the content
of the training recordings' files (:func:`recordings_fingerprint`), the options and the model's code
(``flow.model.checkpoint_key``), with its loss curve (PNG) and a manifest (JSON)
beside it; a model with the same key is loaded instead of trained.

synthesize: audio features of the window's own and partner samples, sampled in overlapping windows
(any length; :meth:`FlowMatchingSystem.synthesize_audio` for a whole conversation without a window),
resampled to the output rate, decoded onto a training recording's skeleton at the character's chair.
It reports no constraints (0 of 0): the paper's audio constraints are not enforced, and the output has
no per-frame provenance (no checker columns).

The partner's audio of a training recording: ``clip.partner_audio_path`` / ``partner_audio_channel``
when the annotation carries them; else the other channel of a two-channel file; else the one other
``<session>_*`` WAV beside the clip's own (the synthetic and GENEA layouts). ``options.partner_audio
false`` leaves the partner out.
"""
from __future__ import annotations

import dataclasses
import json
import logging
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ConfigError
from ..flow.features import (AUDIO_DIM, MotionBasis, Standardizer, audio_features, decode_motion, encode_motion,
                             fit_length, frame_detail_sd,
                             recording_audio_features, resample_features)
from ..flow.joins import smooth_joins
from ..flow.model import FlowModel, FlowParams, checkpoint_key, load_checkpoint, sample_sequence, save_checkpoint, train_flow
from ..fingerprint import stable_hash
from ..utils import atomic_path, file_lock, save_figure
from .base import SynthesisSystem, WindowInput, WindowResult

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class FlowSystemOptions(FlowParams):
    """``system.options`` of ``system=flow_matching``: the model's :class:`FlowParams` plus what only
    the system's sampling uses."""

    join_frames: int = 6    # a window's jump at its first generated frame decays over this many model frames; 0: off
    sample_window_frames: int = 0   # model frames per sampling window; 0: the training window (window_frames)

    def __post_init__(self):
        super().__post_init__()
        if self.sample_window_frames and self.sample_window_frames <= self.prefix_frames:
            raise ConfigError(f"flow_matching: sample_window_frames must be 0 or above prefix_frames "
                              f"({self.prefix_frames}), got {self.sample_window_frames} (system.options)")


def model_params(options: FlowParams) -> FlowParams:
    """The model's own parameters out of the system's options (what training and its cache key see)."""
    return FlowParams(**{f.name: getattr(options, f.name) for f in dataclasses.fields(FlowParams)})


@dataclass
class FlowFit:
    """A character's trained model, its normalisations, the skeleton it writes, and its files."""

    model: FlowModel
    motion_norm: MotionBasis
    audio_norm: Standardizer
    template: Any                 # a training Motion (skeleton, rest offsets)
    seconds: float
    character: str
    checkpoint: str | None = None
    loss_figure: str | None = None
    detail_sd: Any = None         # (D,) the training recordings' frame-level detail at their own rate


def partner_audio_source(clip, siblings: dict | None = None) -> tuple[str, int | None]:
    """(path, channel) of the partner's audio of a training recording (module docstring)."""
    path = getattr(clip, "partner_audio_path", None)
    if path:
        return str(path), getattr(clip, "partner_audio_channel", None)
    own = getattr(clip, "audio_path", None)
    ch = getattr(clip, "audio_channel", None)
    if not own:
        raise ConfigError(f"flow_matching: training recording {clip.session}/{clip.role} has no audio "
                          "(the annotation's audio_path); the model reads the speech")
    if ch in (0, 1):
        return str(own), 1 - int(ch)
    own = Path(own)
    others = sorted(p for p in own.parent.glob(f"{clip.session}_*{own.suffix}") if p.resolve() != own.resolve())
    if len(others) != 1:
        raise ConfigError(f"flow_matching: cannot tell the partner's audio of {own} ({len(others)} other "
                          f"'{clip.session}_*{own.suffix}' files beside it); set system.options.partner_audio=false")
    return str(others[0]), None


def recordings_fingerprint(clips, partner_audio: bool = True) -> str:
    """The content of a character's training recordings as the model reads them: each one's session,
    role, character, the digests of its own and (``partner_audio``) its partner's audio file and their
    channels, and the digest of its motion (:mod:`convsynth_jax.fingerprint`), so a recording edited in
    place, or moved to another session, trains again."""
    from ..fingerprint import content_digest, file_digest

    items = []
    for c in clips:
        row = [c.session, c.role, getattr(c, "character", ""), file_digest(c.audio_path), c.audio_channel,
               content_digest(c.motion)]
        if partner_audio:
            path, ch = partner_audio_source(c)
            row += [file_digest(path), ch]
        items.append(row)
    return stable_hash(items, length=24)


def _plot_losses(losses: np.ndarray, every: int, path: Path, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5, 3.2))
    ax.plot((np.arange(len(losses)) + 1) * every, losses, marker="o", ms=3)
    ax.set_xlabel("training step")
    ax.set_ylabel(f"flow-matching loss (mean of {every} steps)")
    ax.set_yscale("log")
    ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    save_figure(fig, path)
    plt.close(fig)


class FlowMatchingSystem(SynthesisSystem):
    produces_hands = True
    needs_audio = True
    options_type = FlowSystemOptions
    fit_procedure = "fit (training)"
    converses_from_audio = True
    synthesis_procedure = "synthesis (sampling)"

    def fit(self, clips, character: str, condition: str, cache_dir=None) -> FlowFit:
        self.condition_options(condition)
        p = model_params(self.options)
        t0 = time.perf_counter()
        mine = [c for c in clips if getattr(c, "character", character) == character]
        if not mine:
            raise ConfigError(f"flow_matching: no training recordings of character {character!r}")
        motions, own, partner = [], [], []
        for c in mine:
            m = encode_motion(c.motion.resample(p.fps))
            if not getattr(c, "audio_path", None):
                raise ConfigError(f"flow_matching: training recording {c.session}/{c.role} has no audio "
                                  "(the annotation's audio_path); the model reads the speech")
            a = fit_length(recording_audio_features(str(c.audio_path), c.audio_channel, float(p.fps)), len(m))
            motions.append(m)
            own.append(a)
            if p.partner_audio:
                path, ch = partner_audio_source(c)
                partner.append(fit_length(recording_audio_features(path, ch, float(p.fps)), len(m)))
        mn = MotionBasis.fit(np.concatenate(motions), p.pca_variance, p.pca_max_components)
        an = Standardizer.fit(np.concatenate(own + partner))
        xs = [mn.apply(m) for m in motions]
        cs = [np.concatenate([an.apply(o)] + ([an.apply(q)] if p.partner_audio else []), axis=1)
              for o, q in zip(own, partner or own)]
        key = checkpoint_key(motions + own + partner, p, extra=f"{character}:{recordings_fingerprint(mine, p.partner_audio)}")
        template = mine[0].motion
        detail = np.median([frame_detail_sd(encode_motion(c.motion)) for c in mine], axis=0)
        if cache_dir is None:
            model = train_flow(xs, cs, p, progress=bool(getattr(self.params, "progress", False)), label=character)
            model.key = key
            return FlowFit(model, mn, an, template, time.perf_counter() - t0, character, detail_sd=detail)
        folder = Path(cache_dir) / "flow_matching"
        ckpt = folder / f"flow_{character}_{key[:16]}.msgpack"
        fig = ckpt.with_name(ckpt.stem + "_loss.png")
        found = load_checkpoint(ckpt, p, key)
        if found is None:   # several processes on one cache folder: the first trains, the others wait and read
            with file_lock(ckpt):
                found = load_checkpoint(ckpt, p, key)
                if found is None:
                    model = train_flow(xs, cs, p, progress=bool(getattr(self.params, "progress", False)),
                                       label=character)
                    model.key = key
                    save_checkpoint(model, ckpt)
                    _plot_losses(model.losses, min(p.log_every, p.train_steps), fig,
                                 f"flow matching, {character}: {len(mine)} recordings, {sum(map(len, xs))} frames")
                    self._write_manifest(ckpt, model, character, mine, sum(map(len, xs)))
                    return FlowFit(model, mn, an, template, time.perf_counter() - t0, character, str(ckpt), str(fig), detail)
        model = found[0]
        log.info("flow matching %s: loaded %s (trained in %.1f s)", character, ckpt, model.seconds)
        return FlowFit(model, mn, an, template, time.perf_counter() - t0, character, str(ckpt), str(fig), detail)

    @staticmethod
    def _write_manifest(ckpt: Path, model: FlowModel, character: str, clips, frames: int) -> None:
        from ..manifest import run_manifest

        data = run_manifest(what="flow-matching checkpoint", character=character, key=model.key,
                            options=asdict(model.params), training_seconds=model.seconds,
                            training_cpu_seconds=model.cpu_seconds,
                            training_frames=int(frames), recordings=[f"{c.session}/{c.role}" for c in clips],
                            loss_first=float(model.losses[0]), loss_last=float(model.losses[-1]),
                            losses=[float(x) for x in model.losses])
        with atomic_path(ckpt.with_name(ckpt.stem + "_manifest.json"), suffix=".json") as tmp:
            Path(tmp).write_text(json.dumps(data, indent=2, default=str) + "\n")

    def fit_seconds(self, model: FlowFit) -> float:
        """Training time (the original training's when the model came from the cache)."""
        return float(model.model.seconds)

    def synthesize(self, model: FlowFit, window: WindowInput, condition: str) -> WindowResult:
        self.condition_options(condition)
        if window.own_audio is None:
            return WindowResult(False, failure="system flow_matching needs the window's own audio (own_audio is None)")
        t0 = time.perf_counter()
        motion = self.synthesize_audio(model, window.own_audio, window.partner_audio, int(window.num_frames),
                                       float(window.fps), int(window.seed), int(window.chair_index),
                                       name=f"flow_matching:{window.session}:{window.role}")
        return WindowResult(True, motion=motion, seconds=time.perf_counter() - t0,
                            diagnostics={"sampling_windows": self._num_windows(model, int(window.num_frames),
                                                                               float(window.fps))})

    def _num_windows(self, model: FlowFit, num_frames: int, fps: float) -> int:
        p = self._sampling_model(model.model).params
        n = int(np.ceil(num_frames * p.fps / fps))
        return 1 if n <= p.window_frames else 1 + int(np.ceil((n - p.window_frames) / (p.window_frames - p.prefix_frames)))

    def synthesize_audio(self, model: FlowFit, own_audio, partner_audio, num_frames: int, fps: float, seed: int,
                         chair_index: int = 0, name: str = "flow_matching"):
        """A Motion of ``num_frames`` frames at ``fps`` for the character of ``model`` from its own audio
        and the partner's (an ``io.Audio`` each; ``partner_audio`` None: silence), placed at chair
        ``chair_index``; any length (overlapping windows). What a conversation task calls for a whole
        conversation: no transcript and no annotation are read."""
        p = model.model.params
        n = int(np.ceil(num_frames * p.fps / fps))
        cond = [model.audio_norm.apply(audio_features(own_audio, n, p.fps))]
        if p.partner_audio:
            cond.append(model.audio_norm.apply(audio_features(partner_audio, n, p.fps)))
        sampler = self._sampling_model(model.model)
        x = sample_sequence(sampler, np.concatenate(cond, axis=1), seed)
        x = smooth_joins(x, sampler.params.window_frames, p.prefix_frames, int(self.options.join_frames))
        return self._decode(model, x, num_frames, fps, seed, chair_index, name, bool(p.detail_noise))

    def _sampling_model(self, model: FlowModel) -> FlowModel:
        """``model`` sampling in windows of ``options.sample_window_frames`` (the network is convolutional:
        a window longer than the training window reads, at each frame, what a training window does)."""
        w = int(self.options.sample_window_frames)
        if not w or w == model.params.window_frames:
            return model
        found = model._fns.get(("window", w))
        if found is None:
            found = model._fns[("window", w)] = dataclasses.replace(
                model, params=dataclasses.replace(model.params, window_frames=w), _fns={})
        return found

    @staticmethod
    def _decode(model: FlowFit, x: np.ndarray, num_frames: int, fps: float, seed: int, chair_index: int, name: str,
                detail_noise: bool):
        """The Motion of model-space frames ``x`` (n, K): back to features, resampled to ``num_frames``
        at ``fps``, the frame-level detail added (``detail_noise``), decoded at chair ``chair_index``."""
        from ..synth.pipeline import CHAIRS

        p = model.model.params
        feats = resample_features(model.motion_norm.invert(x), num_frames, p.fps / fps)
        if detail_noise and model.detail_sd is not None:   # the recordings' frame-level detail, white
            rng = np.random.default_rng([int(seed) & 0x7FFFFFFF, 1])
            feats = feats + rng.normal(size=feats.shape) * np.asarray(model.detail_sd)[None, :]
        chair, yaw = CHAIRS.get(int(chair_index), CHAIRS[0])
        return decode_motion(feats, model.template, fps, chair, yaw, name)

    def represent(self, model: FlowFit, motion, seed: int = 0, detail_noise: bool = False, chair_index: int = 0):
        """``motion`` through the model's representation alone, no network: encoded, resampled to the
        model's rate, projected on its principal components and back, resampled to ``motion``'s rate and
        decoded as samples are (with the frame-level detail when ``detail_noise``). The floor of what
        the model's space, rate and decoding can show (a control of the evaluation)."""
        p = model.model.params
        x = model.motion_norm.apply(encode_motion(motion.resample(p.fps)))
        return self._decode(model, x, motion.num_frames, motion.fps, seed, chair_index,
                            f"{motion.name}:represented", detail_noise)


__all__ = ["FlowFit", "FlowMatchingSystem", "partner_audio_source", "recordings_fingerprint", "AUDIO_DIM"]
