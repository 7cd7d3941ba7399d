"""Typed parameters of the field-standard metrics (``conf/task/benchmark.yaml``, ``metrics:``)."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Tuple

from ...errors import ConfigError
from ...rig import FINGER_PATTERN

# Legs and feet: left out of the upper body that beat consistency reads.
LOWER_BODY_PATTERN = r"(up_?leg|leg|knee|foot|ankle|toe|thigh|calf|shin)"


@dataclass(frozen=True)
class JointSetParams:
    """Which joints the metrics read (regexes on joint names, case-insensitive).

    exclude: joints left out of every metric (default: fingers, as GENEA's "body without fingers");
    lower_body: joints further left out of beat consistency's upper body."""

    exclude: str = FINGER_PATTERN
    lower_body: str = LOWER_BODY_PATTERN


@dataclass(frozen=True)
class HistogramParams:
    """GENEA's histograms of moving distance (speed, units/s; acceleration, units/s^2): bins of
    ``*_bin_width`` from 0 to ``*_max``, one more bin for every larger value (GENEA drops them)."""

    speed_bin_width: float = 1.0
    speed_max: float = 100.0
    acceleration_bin_width: float = 10.0
    acceleration_max: float = 1500.0

    def __post_init__(self):
        for name in ("speed", "acceleration"):
            w, m = getattr(self, f"{name}_bin_width"), getattr(self, f"{name}_max")
            if w <= 0 or m < w:
                raise ConfigError(f"metrics.histogram: need 0 < {name}_bin_width <= {name}_max, got {w}, {m}")


@dataclass(frozen=True)
class CCAParams:
    """Canonical correlation analysis: ``ridge`` is added to each covariance's diagonal, relative
    to its mean variance. Speech features (speech-motion CCA, Sadoughi and Busso's CCA_ms): F0 and
    log energy and their first derivatives at the motion frame rate (``f0_floor``/``f0_ceiling`` Hz
    for Praat's tracker, ``energy_window`` s)."""

    ridge: float = 1e-6
    f0_floor: float = 75.0
    f0_ceiling: float = 500.0
    energy_window: float = 0.04


@dataclass(frozen=True)
class FGDParams:
    """Fréchet gesture distance. ``eps``: added to both covariances' diagonals when the product's
    square root is not finite (the usual retry); raw windows: ``raw_window_frames`` frames (stride
    half a window) of root-relative positions, every ``raw_frame_step``-th frame kept."""

    eps: float = 1e-6
    raw_window_frames: int = 30
    raw_frame_step: int = 10

    def __post_init__(self):
        if self.raw_window_frames < 2 or self.raw_frame_step < 1:
            raise ConfigError("metrics.fgd: raw_window_frames >= 2 and raw_frame_step >= 1 required")


@dataclass(frozen=True)
class AutoencoderParams:
    """The motion autoencoder whose latent features the FGD compares (GENEA 2022's design; ours to
    train: on motion disjoint from every evaluated window, see ``docs/metrics.md``).

    window_frames: one autoencoder per window length (stride half a window); channels: the
    encoder's 1-D convolutions (the third has stride 2); dense: the dense layers after them, the
    last one the latent size; epochs, batch_size, learning_rate: Adam's; velocity_weight: weight
    of the L1 velocity loss beside the L1 reconstruction; seed: initialisation and batch order."""

    window_frames: Tuple[int, ...] = (30, 60, 90)
    channels: Tuple[int, ...] = (128, 64, 64, 32)
    dense: Tuple[int, ...] = (256, 128, 32)
    kernel_size: int = 5
    epochs: int = 20
    batch_size: int = 64
    learning_rate: float = 1e-3
    velocity_weight: float = 1.0
    seed: int = 0

    def __post_init__(self):
        if not self.window_frames or any(w < 4 or w % 2 for w in self.window_frames):
            raise ConfigError(f"metrics.autoencoder.window_frames: even lengths >= 4 expected, got {self.window_frames}")
        if len(self.channels) != 4 or len(self.dense) < 1:
            raise ConfigError("metrics.autoencoder: four conv channels and at least one dense layer expected")


@dataclass(frozen=True)
class BeatParams:
    """Beat consistency (EMAGE): motion beats are local minima (``order`` frames each side) of each
    upper-body joint's speed divided by its mean, kept where that ratio exceeds ``threshold``; audio
    beats are librosa's onsets (``hop_length`` samples); each motion beat scores
    exp(-d^2 / (2 sigma^2)) for the distance d (s) to the nearest audio beat; ``trim`` s at both ends
    of the window are left out of both streams."""

    sigma: float = 0.3
    order: int = 7
    threshold: float = 0.3
    trim: float = 2.0
    hop_length: int = 512


@dataclass(frozen=True)
class CoverageParams:
    """Gesture area coverage: bones of the root-relative, heading-free pose projected onto the
    frontal plane (``axes``: the two coordinates kept, right and up), rasterised into square cells
    of ``cell`` units over every frame of a window; Dice of the cell sets of system and ground truth."""

    cell: float = 2.0
    axes: Tuple[int, int] = (0, 1)


@dataclass(frozen=True)
class FieldMetricParams:
    joints: JointSetParams = field(default_factory=JointSetParams)
    histogram: HistogramParams = field(default_factory=HistogramParams)
    cca: CCAParams = field(default_factory=CCAParams)
    fgd: FGDParams = field(default_factory=FGDParams)
    autoencoder: AutoencoderParams = field(default_factory=AutoencoderParams)
    beat: BeatParams = field(default_factory=BeatParams)
    coverage: CoverageParams = field(default_factory=CoverageParams)
    bootstrap: int = 1000          # resamples of the windows for the leaderboard's 95% intervals
    bootstrap_set_level: int = 100  # resamples for set-level metrics (FGD, diversity, CCA)
    seed: int = 0
    noise_levels: Tuple[float, ...] = (0.5, 1.0, 2.0, 4.0)  # validity: Gaussian noise SDs (units)
    shuffle_block: float = 1.0     # validity: block length (s) of the shuffled ground truth
