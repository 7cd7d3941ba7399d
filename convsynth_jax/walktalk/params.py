"""Parameters of the walk-the-talk system (Wang et al., "Walk the Talk"), as frozen dataclasses.

The defaults here mirror ``conf/walktalk/default.yaml`` (a test composes the config and compares).
Values the paper gives are marked (paper); every other default is ours and says so in the YAML.
Library functions take these objects; tasks build them once from the ``walktalk`` group with
:func:`convsynth_jax.schema.build_params` (``convsynth_jax.config.group_params``).
"""
from __future__ import annotations

from dataclasses import dataclass, field

from ..errors import WalkTalkError


@dataclass(frozen=True)
class GaitParams:
    """Contact / heel-strike detection (Sec. 3.1, 4). Heights and speeds in cm, cm/s."""

    height_tol_cm: float = 3.0        # a foot is down when ankle or toe is this close to its lowest height
    speed_tol_cms: float = 50.0       # ... and that point moves slower than this horizontally
    # contact/flight phases (Sec. 3.1; thresholds relative to the labelled frames' own motion, ours)
    near_ground_frac: float = 0.5     # walking: a foot is near the ground within this share of its swing clearance
    pass_frac: float = 0.5            # walking: legs passing (flight) while the feet are closer than this share of the step
    jog_ground_frac: float = 0.1      # jogging, second reading: a foot on the ground within this share of its clearance
    min_down_frames: int = 2          # shorter down runs are noise
    jog_flight_frac: float = 0.05     # a clip with this fraction of frames with both feet up is a jog
    max_root_travel_cm: float = 20.0  # a gesture clip whose root moves farther than this is not standing

    def __post_init__(self):
        for name in ("near_ground_frac", "pass_frac", "jog_ground_frac"):
            v = getattr(self, name)
            if not 0.0 <= v <= 1.0:
                raise WalkTalkError(f"{name} must lie in [0, 1], got {v}", where=f"walktalk.gait.{name}")


@dataclass(frozen=True)
class PhaseParams:
    """Automatic gesture-phase detection from root-relative wrist excursion and speed (ours)."""

    rest_frames: int = 3              # the rest pose is the mean of this many first frames
    active_frac: float = 0.03         # active (preparation..retraction end) where excursion > frac * max
    stroke_frac: float = 0.85         # stroke/hold where excursion > frac * max
    peak_prominence_frac: float = 0.25  # a stroke peak is a wrist-speed minimum with this prominence (x max speed)
    hand_min_cm: float = 15.0         # a hand gestures when its excursion exceeds this ...
    hand_rel_frac: float = 0.3        # ... and this fraction of the other hand's


@dataclass(frozen=True)
class SpliceParams:
    """Stylization (Sec. 4.1), synchronization (Sec. 4.2) and splicing (Sec. 4.3)."""

    c: float = 3.0                    # (paper) arm DOFs within +- c std of the loop
    k_bounce: float = 1.0             # elbow bounce, degrees of elbow DOF per cm of root height change (ours)
    # (ours) how the bounce meets the c-sigma band: "reserve" = the stylization leaves the bounce's
    # room free in the elbow DOF's band, then the bounce is added; "rescale" = the bounced deviation
    # is rescaled once more into the band (only with respect_joint_limits), which moves the stroke's
    # level by wherever the bounce peaks (see README, elbow tracking)
    bounce_fit: str = "reserve"
    lead_s: float = 0.2               # nominal stroke-peak lead before the stress peak (paper window 0.2-0.6)
    max_shift_s: float = 0.6          # (paper) search this far earlier for a contact phase
    stylize_deictic: bool = False     # (paper) deictic gestures are not stylized
    ease: str = "smootherstep"        # blend ramp: "linear" = Eq. 2 as printed; smootherstep is ours
    transition_pad_s: float = 0.25    # hold the gesture's rest pose this long before/after and blend over it (ours)
    # (ours) the c-sigma band is also cut at the range of motion of the clip library: per-DOF
    # percentiles of every loaded clip's arm DOFs (the same table the evaluation scores against)
    respect_joint_limits: bool = True
    joint_limit_percentiles: tuple = (0.5, 99.5)
    # (ours) how the band meets the range of motion: "hard" = each side cut at the limit (min);
    # "soft" = a smooth saturation (softplus of width joint_limit_softness_deg) that approaches the
    # limit without reaching it, so a loop whose band would pass the limit still moves the stroke
    joint_limit_mode: str = "hard"
    joint_limit_softness_deg: float = 10.0
    # (ours) the std the band is built from: "loop" = the loop's own (paper); "gait_min" = per DOF
    # the smallest std over the loaded loops of the same gait (never more than the loop's own, so
    # strokes stay within the loop's +- c sigma; the stroke's excursion past B_L is then the same
    # on every loop of a gait and only B_L moves it: the within-gait elbow tracking option)
    band_std: str = "loop"
    # (ours) how the stylization's per-DOF rescale factors are coupled within a joint: 0 = one
    # factor per DOF (paper); 1 = one per joint, its DOFs' smallest (the joint's channels shrink
    # together, which keeps the recording's inter-channel coordination and the wrist jerk near a
    # splice within 2x, at the price of smaller gestures); in between s^(1-g) * s_min^g
    # (see splice.stylize_kernel)
    rescale_coupling: float = 0.0

    def __post_init__(self):
        if not self.c > 0:
            raise WalkTalkError(f"stylization constant c must be > 0, got {self.c}", where="walktalk.splice.c")
        if self.bounce_fit not in ("reserve", "rescale"):
            raise WalkTalkError(f"bounce_fit must be reserve or rescale, got {self.bounce_fit!r}",
                                where="walktalk.splice.bounce_fit")
        if self.joint_limit_mode not in ("hard", "soft"):
            raise WalkTalkError(f"joint_limit_mode must be hard or soft, got {self.joint_limit_mode!r}",
                                where="walktalk.splice.joint_limit_mode")
        if not self.joint_limit_softness_deg > 0:
            raise WalkTalkError(f"joint_limit_softness_deg must be > 0, got {self.joint_limit_softness_deg}",
                                where="walktalk.splice.joint_limit_softness_deg")
        if self.band_std not in ("loop", "gait_min"):
            raise WalkTalkError(f"band_std must be loop or gait_min, got {self.band_std!r}",
                                where="walktalk.splice.band_std")
        if not 0.0 <= self.rescale_coupling <= 1.0:
            raise WalkTalkError(f"rescale_coupling must be in [0, 1], got {self.rescale_coupling}",
                                where="walktalk.splice.rescale_coupling")
        if self.max_shift_s < 0 or self.lead_s < 0:
            raise WalkTalkError("lead_s and max_shift_s must be >= 0", where="walktalk.splice")


@dataclass(frozen=True)
class GazeParams:
    """Gaze and attention (Sec. 5)."""

    r_min: float = 0.6                # (paper) torso/neck yaw = r * theta_yaw, r uniform in [r_min, r_max]
    r_max: float = 1.0                # (paper)
    # share of the yaw per joint, spine to head (ours; the paper says "spine and neck DOFs")
    joint_shares: dict = field(default_factory=lambda: {"Spine": 0.2, "Chest": 0.3, "Neck": 0.25, "Head": 0.25})
    lean_max_deg: float = 15.0        # (paper) lean at most this much
    lean_distance_m: float = 1.0      # (paper) lean only when the addressee is this far ahead / behind
    lean_full_m: float = 2.0          # lean reaches lean_max_deg at this distance (ours)
    lean_joint: str = "Spine"
    max_yaw_deg: float = 90.0         # torso+neck yaw clipped to this (ours)
    # statistics-driven AAR: gaze-at / gaze-away durations in s (mean, sd) -- ours, the paper gives none
    gaze_at_s: tuple = (2.0, 0.5)
    gaze_away_s: tuple = (1.5, 0.5)

    def __post_init__(self):
        for name in ("r_min", "r_max"):
            v = getattr(self, name)
            if not 0.0 <= v <= 1.0:
                raise WalkTalkError(f"{name} must lie in [0, 1], got {v}", where=f"walktalk.gaze.{name}")
        if self.r_min > self.r_max:
            raise WalkTalkError(f"r_min {self.r_min} > r_max {self.r_max}", where="walktalk.gaze")


@dataclass(frozen=True)
class WalkTalkParams:
    data_dir: str = ""                # BVH folder with walk/run/gesture clips ("" = ../shared/data/bandai2/bvh)
    fps: float = 30.0
    walk_glob: str = "*_walk_normal_*.bvh"
    jog_glob: str = "*_run_normal_*.bvh"
    gesture_globs: tuple = ("*raise-up-*.bvh", "*wave-*.bvh")
    # clips pooled into the range-of-motion / joint-limit table only (never spliced): with the walks,
    # runs and gestures above, every clip of the bandai2 set (walk-turns included; docs/decisions.md#walk-the-talk-what-a-good-splice-is)
    limit_globs: tuple = ("*_walk-turn-*.bvh",)
    phases_csv: str = ""              # optional CSV overriding detected phases
    seed: int = 0
    gait: GaitParams = GaitParams()
    phases: PhaseParams = PhaseParams()
    splice: SpliceParams = SpliceParams()
    gaze: GazeParams = GazeParams()
