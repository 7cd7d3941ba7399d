"""Parameters of motion-graph construction (paper Section 6); ``conf/graph`` and ``conf/features``."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Dict, Optional

from ..errors import ConfigError


@dataclass(frozen=True)
class FeatureParams:
    """Pose features of the transition cost (Eq. 3-4)."""

    fps: float = 30.0              # motion is resampled to this rate on load
    up_axis: int = 1               # Y up
    remove_yaw: bool = True        # root-relative positions also undo the root heading
    finger_pattern: Optional[str] = None  # regex of zero-weight (finger) joints; None = built-in pattern
    joint_weight_overrides: Dict[str, float] = field(default_factory=dict)
    # weight w_b of the finger joints (those matching finger_pattern) in Eq. 4: the paper sets 0; a
    # positive value (ours) makes the cost see finger pose and velocity. joint_weight_overrides win.
    finger_weight: float = 0.0

    def __post_init__(self):
        if not float(self.finger_weight) >= 0.0:
            raise ConfigError(f"finger_weight must be >= 0, got {self.finger_weight}", where="features.finger_weight")


@dataclass(frozen=True)
class GraphParams:
    k: int = 3                       # threshold from the distribution of c(i, i+k)
    quantile: float = 0.95           # quantile of the fitted distribution used as the threshold
    # johnsonsb, or auto (lowest residual sum of squares), gamma, lognorm, weibull_min, beta, johnsonsu, expon
    distribution: str = "johnsonsb"
    key_fraction: float = 0.2225     # fraction of frames that are key states (paper: 22.25%); 1.0 = every frame
    use_audio_keys: bool = True      # audio-status changes are key states
    # velocity weight; auto (ours) = mean d(p_i, p_i+k-1) / mean d(v_i, v_i+k-1) over k-step pairs
    w_v: Any = "auto"
    min_gap_frames: int = 10         # no synthetic transition between frames this close in the same clip
    tile: int = 128                  # kernel tile size (frames per side; one compile per size)
    n_pivots: int = 8                # pivot frames for the triangle-inequality tile skipping
    local_minima: bool = False       # keep only local minima of the cost (Kovar et al.)
    max_out_degree: Optional[int] = None  # cap synthetic out-degree per state
    seed: int = 0
    fit_bins: int = 100
    # ours: also fit every other candidate distribution (stats/fits.py CANDIDATES) into meta['fit_table'];
    # false (default): only the configured one (the threshold is the same; ``auto`` always fits all)
    fit_all_candidates: bool = False
    max_edges: Optional[int] = 50_000_000  # host edge-buffer capacity; more raise a GraphError (None: unbounded)
    workers: Optional[int] = None    # host threads dispatching kernel tiles (None: CPU count, at most 4)
    # seam filter (ours, graph/seams.py; None = off, the paper): drop synthetic transitions with a frame
    # faster than this quantile of the database's per-frame largest root-relative acceleration within
    # seam_filter_radius frames of their source or destination frame
    seam_filter_quantile: Optional[float] = None
    seam_filter_radius: int = 4
    # glitch filter (ours, graph/seams.py; 0 = off, the default): drop synthetic transitions with a step
    # in which some joint turns more than this many degrees (a marker-swap glitch: 16-180 degrees in
    # the synthetic corpus; clean motion at most 11.8 in 99.9% of steps) within seam_filter_radius
    # frames of their source or destination frame, so no seam shows a glitch; preset=quality sets 15
    glitch_max_step_deg: float = 0.0

    def __post_init__(self):
        q = self.seam_filter_quantile
        if q is not None and not 0.0 < float(q) < 1.0:
            raise ConfigError(f"seam_filter_quantile must lie in (0, 1) or be null (off), got {q}",
                              where="graph.seam_filter_quantile")
        if float(self.glitch_max_step_deg) < 0:
            raise ConfigError(f"glitch_max_step_deg must be >= 0 degrees (0: off), got {self.glitch_max_step_deg}",
                              where="graph.glitch_max_step_deg")
        if int(self.seam_filter_radius) < 0:
            raise ConfigError(f"seam_filter_radius must be >= 0 frames, got {self.seam_filter_radius}",
                              where="graph.seam_filter_radius")
