"""Parameters of the realization (paper Section 7.3); ``conf/synth``."""
from __future__ import annotations

from dataclasses import dataclass

from ..errors import ConfigError


@dataclass(frozen=True)
class SynthParams:
    # cosine blend length after a synthetic transition (the paper gives none; ours: 12 frames = 0.4 s at
    # 30 fps; on leave-one-out fold 0 the largest seam_ratio was 1.87 with 6 frames, 0.84 with 12)
    blend_frames: int = 12
    # how a synthetic transition is smoothed: "cosine" (the paper, Section 7.1: the previous clip's
    # continuation cross-faded into the new source with cosine weights, slerp) or "inertialize"
    # (ours: the offset between the displayed stream and the new source, in value and velocity,
    # decayed to zero by a quintic over blend_frames frames; realize.inertialized_blend)
    blend_method: str = "cosine"
    # a blend's old stream (the previous clip's continuation, and an interrupted layer's) holds at the
    # last frame before a step in which some joint turns more than this many degrees (ours, off by default):
    # a marker-swap glitch of the source is never faded in through a blend. Clean motion of the
    # synthetic corpus turns at most 11.8 degrees a frame in 99.9% of its steps, its glitches enter
    # with 16-180 degrees; preset=quality sets 15. 0 (default, the paper): off (the continuation plays
    # whatever its clip has)
    continuation_max_step_deg: float = 0.0
    # retiming (search.retime_factor > 0): drop the warp's returns to the identity next to a retimed segment
    # where they would play the path slower than this many path frames per output frame, so the shift
    # spreads over the whole idle run (ours, synth/retime.spread_slow_stretches; 0, the default: off,
    # the warp as search/retime.py gives it)
    retime_min_speed: float = 0.0
    # retiming: warp only the motion's moving average over this many frames and put each frame's detail
    # back at the output rate, so a slowed stretch keeps the recording's frame-to-frame motion (ours,
    # synth/retime.warp_motion; 0, the default: off, the whole motion interpolated through the warp)
    retime_detail_frames: int = 0
    # a cosine blend keeps the new source's frame-to-frame detail: its joint rotations are the blend's
    # moving average over this many frames times the source's own offset from its moving average (ours,
    # synth/realize.keep_source_detail; 0, the default: off, the paper's plain cross-fade)
    blend_detail_frames: int = 0
    # penalties on synthetic edges, in multiples of the graph's median synthetic edge cost, that the
    # motion-graph system adds when it loads a graph (ours, systems/motion_graph.penalized_graph; the
    # cached graph is unchanged, the search temperature keeps its unit): transition_penalty on every
    # synthetic edge (paths with fewer transitions), loop_penalty on every synthetic edge back to an
    # earlier frame of the same clip (paths that do not replay what they have just shown). 0 (default,
    # the paper): off
    transition_penalty: float = 0.0
    loop_penalty: float = 0.0
    # a synthetic edge into a hub costs more (ours, graph/hubs.py): hub_penalty x the median synthetic
    # cost x min(the target's synthetic in-degree / the mean in-degree, hub_cap), so transitions spread
    # over the recordings instead of converging on the near-mean states most edges enter. 0 (default,
    # the paper): off
    hub_penalty: float = 0.0
    hub_cap: float = 16.0
    hub_ends: str = "target"    # "both": the mean of the target's relative in-degree and the source's out-degree

    def __post_init__(self):
        if not float(self.hub_penalty) >= 0:
            raise ConfigError(f"hub_penalty must be >= 0 (0: off), got {self.hub_penalty}", where="synth.hub_penalty")
        if not float(self.hub_cap) > 0:
            raise ConfigError(f"hub_cap must be > 0, got {self.hub_cap}", where="synth.hub_cap")
        if self.hub_ends not in ("target", "both"):
            raise ConfigError(f"hub_ends must be target or both, got {self.hub_ends!r}", where="synth.hub_ends")
