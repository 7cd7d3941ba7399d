"""One character's synthesis for one window: constraints -> search -> realization -> blinks."""
from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from ..errors import ConfigError
from ..search.beam import beam_search
from ..search.constraints import build_constraints
from ..search.dfs import stochastic_greedy_search
from ..search.params import SearchParams
from .blinks import blink_curve, blink_times
from .params import SynthParams
from .realize import realize

log = logging.getLogger(__name__)

CHAIRS = {0: ((0.0, 0.0, -60.0), 0.0), 1: ((0.0, 0.0, 60.0), 180.0)}
# search.method -> search function (graph, constraints, SearchParams, seed) -> SearchResult
SEARCHES = {"beam": beam_search, "dfs": stochastic_greedy_search}


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
    synthetic_at: list = field(default_factory=list)  # output frames where a synthetic transition arrives


def synthesize_character(graph, clip_motions: dict, own_segments, partner_segments, num_frames: int,
                         search: SearchParams, synth: SynthParams, seed: int = 0,
                         chair_index: int = 0) -> SynthesisResult:
    """Constraints from the window's audio segments -> the search named by ``search.method`` ->
    realization at the chair ``chair_index`` -> blinks."""
    fps = graph.fps
    method = search.method
    if method not in SEARCHES:
        raise ConfigError(f"search.method must be one of {sorted(SEARCHES)}, got {method!r}")
    cons = build_constraints(own_segments, partner_segments, num_frames, fps, search)
    res = SEARCHES[method](graph, cons, search, seed=seed)
    if not res.success:
        seg = res.failed_segment or {}
        why = res.failure or (f"no path satisfies the {seg.get('kind', '?')} constraint at frames "
                              f"{seg.get('start')}-{seg.get('end')}")
        return SynthesisResult(False, constraints_total=cons.total, search_seconds=res.seconds, failure=why,
                               method=method)
    path = res.path
    clips = [graph.clip_names[int(graph.clip[s])] for s in path]
    frames = [int(graph.frame[s]) for s in path]
    syn_at = res.synthetic_at or []
    chair, yaw = CHAIRS.get(chair_index, CHAIRS[0])
    motion = realize(clips, frames, clip_motions, syn_at, chair=chair, chair_yaw_deg=yaw,
                     blend_frames=int(synth.blend_frames), blend_method=str(synth.blend_method))
    rng = np.random.default_rng(seed)
    peaks = [] if own_segments is None else own_segments.loc[own_segments["kind"] == "PC", "peak"].to_numpy()
    bt = blink_times(peaks, num_frames / fps, rng)
    return SynthesisResult(True, motion, path, clips, frames, res.cost, res.num_synthetic_transitions,
                           res.constraints_total, res.constraints_met, res.seconds, blink_curve(bt, num_frames, fps),
                           None, res.transition_costs or [], method, list(syn_at))

