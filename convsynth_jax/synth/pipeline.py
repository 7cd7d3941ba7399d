"""One character's synthesis for one window: constraints -> search -> realization -> blinks."""
from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from ..search.beam import beam_search
from ..search.constraints import _get, build_constraints
from ..search.dfs import stochastic_greedy_search
from .blinks import blink_curve, blink_times
from .realize import realize

log = logging.getLogger(__name__)

CHAIRS = {0: ((0.0, 0.0, -60.0), 0.0), 1: ((0.0, 0.0, 60.0), 180.0)}


@dataclass
class SynthesisResult:
    success: bool
    motion: object = None
    path: np.ndarray | None = None
    source_clip: list = field(default_factory=list)
    source_frame: list = field(default_factory=list)
    cost: float = float("inf")
    num_synthetic_transitions: int = 0
    constraints_total: int = 0
    constraints_met: int = 0
    search_seconds: float = 0.0
    blinks: np.ndarray | None = None
    failure: str | None = None
    transition_costs: list = field(default_factory=list)
    method: str = ""


def synthesize_character(graph, clip_motions: dict, own_segments, partner_segments, num_frames: int, cfg=None,
                         seed: int = 0, method: str = "beam", chair_index: int = 0) -> SynthesisResult:
    fps = graph.fps
    cons = build_constraints(own_segments, partner_segments, num_frames, fps, cfg)
    search = beam_search if method == "beam" else stochastic_greedy_search
    res = search(graph, cons, cfg, seed=seed)
    if not res.success:
        seg = res.failed_segment or {}
        why = f"no path satisfies the {seg.get('kind', '?')} constraint at frames {seg.get('start')}-{seg.get('end')}"
        return SynthesisResult(False, constraints_total=cons.total, search_seconds=res.seconds, failure=why,
                               method=method)
    path = res.path
    clips = [graph.clip_names[int(graph.clip[s])] for s in path]
    frames = [int(graph.frame[s]) for s in path]
    syn_at = res.synthetic_at or []
    chair, yaw = CHAIRS.get(chair_index, CHAIRS[0])
    s = cfg.get("synth", {}) if cfg is not None and hasattr(cfg, "get") else {}
    blend = int((s or {}).get("blend_frames", 6))
    motion = realize(clips, frames, clip_motions, syn_at, chair=chair, chair_yaw_deg=yaw, blend_frames=blend)
    rng = np.random.default_rng(seed)
    peaks = [] if own_segments is None else own_segments.loc[own_segments["kind"] == "PC", "peak"].to_numpy()
    bt = blink_times(peaks, num_frames / fps, rng)
    return SynthesisResult(True, motion, path, clips, frames, res.cost, res.num_synthetic_transitions,
                           res.constraints_total, res.constraints_met, res.seconds, blink_curve(bt, num_frames, fps),
                           None, res.transition_costs or [], method)

