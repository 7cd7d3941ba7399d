"""One character's synthesis for one window: constraints -> search -> realization -> blinks.

``search.on_failure=best_effort`` (ours): a window no path solves gets the best-effort path of
``search/relax.py``; its met and unmet constraints are the independent checker's
(``search/check.py``, on the annotation the graph stores). ``search.retime_factor`` > 0 (ours): the
realized motion is warped so the matched clauses land on the input's times (``synth/retime.py``)."""
from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from ..errors import ConfigError
from ..search.beam import beam_search
from ..search.check import check_path, clip_audio_of_graph
from ..search.constraints import build_constraints
from ..search.dfs import stochastic_greedy_search
from ..search.params import SearchParams
from ..search.relax import best_effort_search, check_on_failure
from ..search.result import explained, next_step
from ..search.retime import retime_knots
from .blinks import blink_curve, blink_times
from .params import SynthParams
from .realize import realize
from .retime import spread_slow_stretches, warp_motion

log = logging.getLogger(__name__)

CHAIRS = {0: ((0.0, 0.0, -60.0), 0.0), 1: ((0.0, 0.0, 60.0), 180.0)}
# search.method -> search function (graph, constraints, SearchParams, seed) -> SearchResult; a failure
# under the paper's rule ends with what would make motion (search/result.py: next_step)
SEARCHES = {"beam": explained(beam_search), "dfs": explained(stochastic_greedy_search)}


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
    best_effort: bool = False      # search.on_failure=best_effort found no path meeting every constraint
    met: list = field(default_factory=list)    # best effort or retiming: the checker's met constraints
    unmet: list = field(default_factory=list)  # ... and unmet ones (dicts: kind, start, end, peak in frames)
    claimed: dict | None = None    # best effort: (kind, start, end) -> met as the search claims (search/relax.py)
    warp: tuple | None = None      # retiming: (output knots, path knots) in frames


def synthesize_character(graph, clip_motions: dict, own_segments, partner_segments, num_frames: int,
                         search: SearchParams, synth: SynthParams, seed: int = 0,
                         chair_index: int = 0) -> SynthesisResult:
    """Constraints from the window's audio segments -> the search named by ``search.method`` ->
    realization at the chair ``chair_index`` -> blinks."""
    fps = graph.fps
    method = search.method
    if method not in SEARCHES:
        raise ConfigError(f"search.method must be one of {sorted(SEARCHES)}, got {method!r}")
    on_failure = check_on_failure(search)
    cons = build_constraints(own_segments, partner_segments, num_frames, fps, search)
    res = SEARCHES[method](graph, cons, search, seed=seed)
    if not res.success and on_failure == "best_effort":
        log.info("no path meets every constraint (%s); best effort", res.failure)
        first = res.seconds
        plain = getattr(SEARCHES[method], "unexplained", SEARCHES[method])   # its failures are not the user's
        res = best_effort_search(plain, graph, own_segments, partner_segments, num_frames, fps, search, seed=seed)
        res.seconds += first
        if res.success:
            cons = build_constraints(own_segments, partner_segments, num_frames, fps, search,
                                     relaxed=frozenset(res.relaxed))
    if not res.success:
        seg = res.failed_segment or {}
        why = res.failure or " ".join(x for x in (f"no path satisfies the {seg.get('kind', '?')} constraint at "
                                                   f"frames {seg.get('start')}-{seg.get('end')}.",
                                                   next_step(search, seg)) if x)
        return SynthesisResult(False, constraints_total=cons.total, search_seconds=res.seconds, failure=why,
                               method=method)
    path = res.path
    clips = [graph.clip_names[int(graph.clip[s])] for s in path]
    frames = [int(graph.frame[s]) for s in path]
    syn_at = res.synthetic_at or []
    chair, yaw = CHAIRS.get(chair_index, CHAIRS[0])
    motion = realize(clips, frames, clip_motions, syn_at, chair=chair, chair_yaw_deg=yaw,
                     blend_frames=int(synth.blend_frames), blend_method=str(synth.blend_method),
                     max_step_deg=float(synth.continuation_max_step_deg),
                     detail_frames=int(synth.blend_detail_frames))
    warp = retime_knots(graph, cons, path, float(search.retime_factor)) if float(search.retime_factor) > 0 else None
    if warp is not None and float(synth.retime_min_speed) > 0:
        warp = spread_slow_stretches(*warp, float(synth.retime_min_speed))
    if warp is not None:
        motion = warp_motion(motion, *warp, detail_frames=int(synth.retime_detail_frames))
    met, unmet = [], []
    total, n_met = res.constraints_total, res.constraints_met
    if res.best_effort or warp is not None:   # what the independent checker confirms
        chk = check_path(clips, frames, clip_audio_of_graph(graph), own_segments, partner_segments, fps,
                         float(search.tolerance), bool(search.use_lr), bool(search.use_hp), matching=search.matching,
                         warp=warp)
        met = [{k: d[k] for k in ("kind", "start", "end", "peak")} for d in chk["details"] if d["met"]]
        unmet = [{k: d[k] for k in ("kind", "start", "end", "peak")} for d in chk["details"] if not d["met"]]
        total, n_met = chk["total"], chk["met"]
    rng = np.random.default_rng(seed)
    peaks = [] if own_segments is None else own_segments.loc[own_segments["kind"] == "PC", "peak"].to_numpy()
    bt = blink_times(peaks, num_frames / fps, rng)
    return SynthesisResult(True, motion, path, clips, frames, res.cost, res.num_synthetic_transitions,
                           total, n_met, res.seconds, blink_curve(bt, num_frames, fps),
                           None, res.transition_costs or [], method, list(syn_at), bool(res.best_effort), met, unmet,
                           res.claimed, warp)

