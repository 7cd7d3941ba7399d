"""A floor for every ablation table (ours, not in any paper): random playback of the character's
training motion, ignoring the audio.

The window is filled with excerpts of ``min_excerpt_seconds``-``max_excerpt_seconds`` from random
training clips and positions, concatenated and realized like a motion-graph path (blends at each jump
as ``synth.blend_method`` says, root integrated from the chair), so it differs from the motion graph only in how source
frames are chosen. It reports no constraints (0 of 0).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import ConfigError
from ..synth.pipeline import CHAIRS
from ..synth.realize import realize
from .base import WindowInput, WindowResult
from .playback import PlaybackSystem, clip_name, training_labels


@dataclass
class PlaybackModel:
    motions: dict     # clip name -> Motion
    seconds: float = 0.0
    labels: dict = field(default_factory=dict)  # clip name -> (own, partner) per-frame audio labels


@dataclass(frozen=True)
class RandomPlaybackOptions:
    """``system.options`` of ``system=random_playback``."""

    min_excerpt_seconds: float = 2.0   # play excerpts at least this long before jumping elsewhere
    max_excerpt_seconds: float = 6.0

    def __post_init__(self):
        if not 0 < self.min_excerpt_seconds <= self.max_excerpt_seconds:
            raise ConfigError(f"random_playback: need 0 < min_excerpt_seconds <= max_excerpt_seconds, "
                              f"got {self.min_excerpt_seconds}, {self.max_excerpt_seconds}")


@dataclass(frozen=True)
class RandomPlaybackCondition:
    """A condition of ``system=random_playback`` (it ignores the audio: a condition sets nothing)."""


class RandomPlaybackSystem(PlaybackSystem):
    produces_hands = True
    options_type = RandomPlaybackOptions
    condition_type = RandomPlaybackCondition

    def fit(self, clips, character: str, condition: str, cache_dir=None) -> PlaybackModel:
        motions = {clip_name(c.session, c.role): c.motion for c in clips}
        if not motions:
            raise ConfigError(f"random_playback: no training clips of character {character!r}")
        return PlaybackModel(motions, labels=training_labels(clips))

    def synthesize(self, model: PlaybackModel, window: WindowInput, condition: str) -> WindowResult:
        self.condition_options(condition)
        t0 = time.perf_counter()
        lo, hi = float(self.options.min_excerpt_seconds), float(self.options.max_excerpt_seconds)
        rng = np.random.default_rng(window.seed)
        names = sorted(model.motions)
        n, fps = window.num_frames, window.fps
        clips, frames, jumps = [], [], []
        while len(frames) < n:
            length = int(round(rng.uniform(lo, hi) * fps))
            name = names[rng.integers(len(names))]
            avail = model.motions[name].num_frames
            length = max(1, min(length, avail, n - len(frames)))
            start = int(rng.integers(0, avail - length + 1))
            if frames:
                jumps.append(len(frames))
            clips += [name] * length
            frames += list(range(start, start + length))
        chair, yaw = CHAIRS.get(window.chair_index, CHAIRS[0])
        blend = int(self.params.synth.blend_frames)
        motion = realize(clips, frames, model.motions, jumps, chair=chair, chair_yaw_deg=yaw,
                         blend_frames=blend, blend_method=str(self.params.synth.blend_method))
        return WindowResult(True, motion, time.perf_counter() - t0, 0, 0, None, clips, np.asarray(frames),
                            {"num_synthetic_transitions": len(jumps)}, jumps, blend)
