"""A whole conversation of any length as one continuous motion per character: windows of the input
searched one after the other, each continuing the previous one's path through the graph (ours; the
paper synthesizes one 15 s window at a time).

Windows. The input's frames are cut into windows (:func:`plan_windows`): window k searches the
frames [start_k, search_end_k) (``window_s`` long, the search's usual window) and keeps
[start_k, end_k) (``hop_s``; the frames after end_k are searched as a look-ahead horizon only and
searched again by the next window). Each cut end_k is moved back by at most ``snap_s`` to a frame
where neither speaker has an audio segment (with the search tolerance around it), so a clause is
not split between two windows whenever the audio has a pause nearby. The last window takes the
rest (up to ``window_s + min_last_s``).

Chaining (``chaining="graph"``, the default). Window k > 0 starts from a *successor* of the state the
kept path of window k - 1 ends in: its frame-0 state is restricted to the targets of that state's
``search.max_degree`` cheapest out-edges (``start_states`` of the searches), so the step across the
cut is one edge of the graph, like any step inside a window: the natural continuation of the clip,
or a synthetic transition that the realization blends like every other. If no path of window k
starts there, the cut is moved back by each of ``backoff_s`` in turn: window k then starts earlier,
from a successor of an earlier state of window k - 1's path, and replaces that path's tail. The
whole path is realized at once (:func:`~convsynth_jax.synth.realize.realize`), so the root is
integrated once over the whole conversation and blends run across cuts: there is no seam.

``chaining="independent"`` is the control: every window searched from any state and realized on its
own from the chair, the motions concatenated; each cut is then a seam (the pose and the root jump).
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import ConfigError
from ..search.constraints import build_constraints
from ..search.result import path_stats
from .blinks import blink_curve, blink_times
from .realize import realize

log = logging.getLogger(__name__)

CHAINING_MODES = ("graph", "independent")


@dataclass
class PlannedWindow:
    """Frames [start, end) are kept; [start, search_end) are searched (search_end >= end)."""

    index: int
    start: int
    end: int
    search_end: int


def quiet_mask(segment_tables, num_frames: int, fps: float, margin_frames: int) -> np.ndarray:
    """(num_frames,) bool: True where no segment of any table (seconds; ``margin_frames`` around each)
    covers the frame."""
    busy = np.zeros(num_frames, bool)
    for seg in segment_tables:
        if seg is None or len(seg) == 0:
            continue
        for s, e in zip(seg["start"].to_numpy(float), seg["end"].to_numpy(float)):
            a = max(0, int(np.floor(s * fps)) - margin_frames)
            b = min(num_frames, int(np.ceil(e * fps)) + margin_frames + 1)
            if b > a:
                busy[a:b] = True
    return ~busy


def plan_windows(num_frames: int, fps: float, window_s: float, hop_s: float, snap_s: float = 0.0,
                 min_last_s: float = 5.0, quiet: np.ndarray | None = None) -> list[PlannedWindow]:
    """The windows of a ``num_frames`` input (module docstring). ``quiet``: (num_frames,) bool, frames
    a cut may be moved to (None: cuts stay at multiples of the hop)."""
    W, H = int(round(window_s * fps)), int(round(hop_s * fps))
    snap, min_last = int(round(snap_s * fps)), int(round(min_last_s * fps))
    if W < 1 or H < 1 or H > W:
        raise ConfigError(f"converse windows need 0 < hop <= window (got window {window_s} s, hop {hop_s} s)")
    if snap < 0 or snap >= H:
        raise ConfigError(f"converse snap_s must lie in [0, hop) (got {snap_s} s with hop {hop_s} s)")
    out, c = [], 0
    while True:
        if num_frames - c <= W + min_last:
            out.append(PlannedWindow(len(out), c, num_frames, num_frames))
            return out
        cut = c + H
        if quiet is not None and snap > 0:
            ok = np.flatnonzero(quiet[cut - snap:cut + 1])
            if ok.size:
                cut = cut - snap + int(ok[-1])   # the quiet frame nearest the nominal cut, at or before it
        out.append(PlannedWindow(len(out), c, cut, c + W))
        c = cut


def successors(graph, state: int, max_degree: int) -> np.ndarray:
    """The targets of ``state``'s ``max_degree`` cheapest out-edges (the edges the searches consider)."""
    tg, cost, _ = graph.out_edges(int(state))
    return np.asarray(tg, np.int64)[np.argsort(cost, kind="stable")[:int(max_degree)]]


@dataclass
class ChainResult:
    """One character's conversation. path: (T,) graph state per frame (None unless every window has a
    path); windows: one dict per planned window (index, start, end, search_end in frames, status
    ``ok`` | ``best_effort`` | ``failed`` | ``not_searched``, seconds, seed, backoff frames, failure,
    constraints of the search); motion: the realized Motion (None on failure)."""

    success: bool
    path: np.ndarray | None = None
    source_clip: list = field(default_factory=list)
    source_frame: list = field(default_factory=list)
    synthetic_at: list = field(default_factory=list)
    transition_costs: list = field(default_factory=list)
    cost: float = float("nan")
    motion: object = None
    blinks: np.ndarray | None = None
    windows: list = field(default_factory=list)
    failed_window: int | None = None
    failure: str | None = None
    cuts: list = field(default_factory=list)   # path frames where a window after the first begins
    warp: tuple | None = None   # the retiming warp of the whole path (out knots, path knots), or None
    path_motion: object = None  # the realized motion before the warp (path time: source_clip/frame's index)

    def output_frames(self, path_frames) -> list:
        """Output (audio) frames where the given path frames are shown: the identity without a warp."""
        if self.warp is None:
            return [int(t) for t in path_frames]
        out_k, path_k = (np.asarray(k, np.float64) for k in self.warp)
        return [int(round(float(np.interp(t, path_k, out_k)))) for t in path_frames]


def span_segments(segments, start: float, end: float):
    """Audio segments overlapping [start, end) seconds, times relative to ``start``; segments crossing
    an edge keep their true times (as ``evaluation.windows.window_segments``, which this layer may not import)."""
    import pandas as pd

    if segments is None or len(segments) == 0:
        return pd.DataFrame(columns=["kind", "start", "peak", "end", "text"])
    seg = segments[(segments["end"] > start) & (segments["start"] < end)].copy()
    for col in ("start", "peak", "end"):
        if col in seg:
            seg[col] = seg[col] - start
    return seg.reset_index(drop=True)


def _search(graph, own, partner, w0: int, w1: int, fps: float, search, seed: int, start_states):
    from ..errors import SearchFailure
    from ..search.result import SearchResult
    from .pipeline import SEARCHES

    a, b = w0 / fps, w1 / fps
    cons = build_constraints(span_segments(own, a, b), span_segments(partner, a, b), w1 - w0, fps, search)
    if search.method not in SEARCHES:
        raise ConfigError(f"search.method must be one of {sorted(SEARCHES)}, got {search.method!r}")
    try:
        res = SEARCHES[search.method](graph, cons, search, seed=seed, start_states=start_states)
    except SearchFailure as e:   # a search asked to raise (search.on_failure=fail, where it exists)
        return SearchResult(False, None, float("inf"), 0, cons.total, 0, failure=str(e)), cons
    if not res.success and getattr(search, "on_failure", "fail") == "best_effort":
        # best effort from the allowed start states: the look-ahead drops what no path from there meets
        from ..search.relax import best_effort_search

        first = res.seconds
        res = best_effort_search(SEARCHES[search.method], graph, span_segments(own, a, b), span_segments(partner, a, b),
                                 w1 - w0, fps, search, seed=seed, start_states=start_states)
        res.seconds += first
    return res, cons


def chain_search(graph, own_segments, partner_segments, plan: list[PlannedWindow], fps: float, search,
                 seed_of, backoff_s=(), chaining: str = "graph") -> tuple[np.ndarray | None, list, int | None, str | None]:
    """Search every window of ``plan`` for one character (module docstring). ``seed_of(window_start_frame)``
    -> the window's seed. Returns (path (T,) or None, per-window dicts, failed window index or None,
    failure text). With ``search.on_failure`` (when the search parameters have it) ``best_effort``, a
    window whose search returns a path without meeting every constraint is kept and marked so."""
    if chaining not in CHAINING_MODES:
        raise ConfigError(f"task.chaining must be one of {list(CHAINING_MODES)}, got {chaining!r}")
    T = plan[-1].end
    path = np.full(T, -1, np.int64)
    on_failure = getattr(search, "on_failure", None)
    backoffs = [0] + [int(round(float(b) * fps)) for b in (backoff_s or []) if float(b) > 0]
    rows = [{"index": w.index, "start": w.start, "end": w.end, "search_end": w.search_end, "status": "not_searched",
             "seconds": 0.0} for w in plan]
    for k, w in enumerate(plan):
        row = rows[k]
        t0 = time.perf_counter()
        tried, res = [], None
        for b in backoffs if (k > 0 and chaining == "graph") else [0]:
            s0 = w.start - b
            if k > 0 and s0 <= rows[k - 1]["start"]:
                break
            start = successors(graph, path[s0 - 1], search.max_degree) if (k > 0 and chaining == "graph") else None
            seed = seed_of(w.start) + 7919 * len(tried)
            res, cons = _search(graph, own_segments, partner_segments, s0, w.search_end, fps, search, seed, start)
            tried.append(b)
            if res.success:
                break
        row["seconds"] = time.perf_counter() - t0
        row["seed"] = seed
        row["backoff_frames"] = tried[-1] if tried else 0
        row["attempts"] = len(tried)
        row["search_constraints"] = int(cons.total)
        usable = res.path is not None and (res.success or on_failure == "best_effort")
        if not usable:
            row["status"] = "failed"
            row["failure"] = res.failure or "no path"
            why = (f"window {k} ({w.start / fps:.2f}-{w.end / fps:.2f} s, frames {w.start}-{w.end}) has no path: "
                   f"{row['failure']}")
            if len(tried) > 1:
                why += f" (also tried starting {', '.join(f'{b / fps:.2f}' for b in tried[1:])} s earlier)"
            return None, rows, k, why
        relaxed = bool(getattr(res, "best_effort", False))
        row["status"] = "ok" if res.success and not relaxed else "best_effort"
        if relaxed:
            row["relaxed"] = [list(k) for k in (getattr(res, "relaxed", None) or [])]
        if not res.success:
            row["failure"] = res.failure
        s0 = w.start - row["backoff_frames"]
        if s0 != w.start:   # the previous window keeps less; this one begins earlier
            rows[k - 1]["end"] = s0
            row["start"] = s0
        path[s0:w.end] = np.asarray(res.path, np.int64)[:w.end - s0]
        # progress of a long conversation: one line per window
        log.info("window %d/%d (%.1f-%.1f s): %s, %d constraints (%d relaxed), %.1f s", k + 1, len(plan),
                 s0 / fps, w.end / fps, row["status"], int(cons.total), len(row.get("relaxed", [])), row["seconds"])
    return path, rows, None, None


def realize_chain(graph, motions: dict, path: np.ndarray, cuts, synth, chair, chair_yaw_deg: float,
                  independent: bool = False):
    """(Motion, synthetic transitions (frames), their costs, total cost) of a whole path. ``independent``:
    each window [cuts[i], cuts[i + 1]) realized on its own and the motions concatenated (the control)."""
    clips = [graph.clip_names[int(graph.clip[s])] for s in path]
    frames = [int(graph.frame[s]) for s in path]
    bounds = [0, *[int(c) for c in cuts], len(path)]
    spans = list(zip(bounds[:-1], bounds[1:])) if independent else [(0, len(path))]
    parts, syn_all, costs, total = [], [], [], 0.0
    for a, b in spans:
        cost, tc, at = path_stats(graph, path[a:b])
        at = [a + t for t in at]
        total += cost
        costs += tc
        syn_all += at
        parts.append(realize(clips[a:b], frames[a:b], motions, [t - a for t in at], chair=chair,
                             chair_yaw_deg=chair_yaw_deg, blend_frames=int(synth.blend_frames),
                             blend_method=str(synth.blend_method),
                             max_step_deg=float(synth.continuation_max_step_deg),
                             detail_frames=int(synth.blend_detail_frames)))
    motion = parts[0]
    if len(parts) > 1:
        from ..skeleton import Motion

        motion = Motion(motion.skeleton, np.concatenate([p.rotations for p in parts]),
                        np.concatenate([p.translations for p in parts]), motion.fps, "synthesized")
    return motion, clips, frames, syn_all, costs, total


def synthesize_conversation(graph, motions: dict, own_segments, partner_segments, num_frames: int, fps: float,
                            plan: list[PlannedWindow], search, synth, seed_of, chair_index: int = 0,
                            backoff_s=(), chaining: str = "graph") -> ChainResult:
    """One character's whole conversation: :func:`chain_search`, then :func:`realize_chain` and blinks
    at the character's own clause peaks."""
    from .pipeline import CHAIRS

    if plan[-1].end != num_frames:
        raise ConfigError(f"window plan ends at frame {plan[-1].end}, the input has {num_frames}")
    path, rows, failed, why = chain_search(graph, own_segments, partner_segments, plan, fps, search, seed_of,
                                           backoff_s, chaining)
    if path is None:
        return ChainResult(False, windows=rows, failed_window=failed, failure=why)
    cuts = [r["start"] for r in rows[1:]]
    chair, yaw = CHAIRS.get(chair_index, CHAIRS[0])
    motion, clips, frames, syn_at, costs, total = realize_chain(graph, motions, path, cuts, synth, chair, yaw,
                                                                independent=(chaining == "independent"))
    warp, path_motion = None, motion
    factor = float(getattr(search, "retime_factor", 0.0) or 0.0)
    if factor > 0:
        # the retiming warp of the whole path against the whole conversation's constraints: each matched
        # source segment moved onto the input's times, as the single-window pipeline does
        from ..search.retime import retime_knots
        from .retime import spread_slow_stretches, warp_motion

        whole = build_constraints(own_segments, partner_segments, num_frames, fps, search)
        warp = retime_knots(graph, whole, path, factor)
        if warp is not None and float(synth.retime_min_speed) > 0:
            warp = spread_slow_stretches(*warp, float(synth.retime_min_speed))
        if warp is not None:
            motion = warp_motion(motion, *warp, detail_frames=int(synth.retime_detail_frames))
    rng = np.random.default_rng(seed_of(0))
    peaks = [] if own_segments is None or len(own_segments) == 0 else \
        own_segments.loc[own_segments["kind"] == "PC", "peak"].to_numpy(float)
    blinks = blink_curve(blink_times(peaks, num_frames / fps, rng), num_frames, fps)
    return ChainResult(True, path, clips, frames, syn_at, costs, total, motion, blinks, rows, cuts=cuts, warp=warp,
                       path_motion=path_motion)


def _acc_norms(pos: np.ndarray) -> np.ndarray:
    """(T, J) |p[t+1] - 2 p[t] + p[t-1]| per joint (0 at the first and last frame)."""
    out = np.zeros(pos.shape[:2])
    if len(pos) > 2:
        out[1:-1] = np.linalg.norm(pos[2:] - 2 * pos[1:-1] + pos[:-2], axis=-1)
    return out


def excess_acceleration(motion, motions: dict, source_clip, source_frame) -> np.ndarray:
    """(T,) per output frame, the largest over joints of | |a| - |a_src| |: a the realized joint
    acceleration (world positions, root included; units per frame^2), a_src the acceleration of the
    source clip itself around the frame it plays there (its frames f - 1, f, f + 1). Where the path
    plays a clip on, the realization is the clip moved rigidly and this is 0; a blended transition
    shows the difference its blend makes; a seam (a jump of pose or root) shows its jump. The source
    clip's own movement cancels out, so a fast gesture at a cut is not taken for a seam (ours)."""
    from ..kinematics import forward_kinematics

    T = len(source_frame)
    real = _acc_norms(np.asarray(forward_kinematics(motion), np.float64))
    src = np.zeros_like(real)
    f = np.asarray(source_frame, np.int64)
    n = np.array([motions[c].num_frames for c in source_clip])
    rows = {}
    for d in (-1, 0, 1):   # three motions of T frames (one compiled kernel shape): the source at f + d
        g = np.clip(f + d, 0, n - 1)
        rot = np.stack([motions[c].rotations[k] for c, k in zip(source_clip, g)])
        tr = np.stack([motions[c].translations[k] for c, k in zip(source_clip, g)])
        rows[d] = np.asarray(forward_kinematics(type(motion)(motion.skeleton, rot, tr, motion.fps)), np.float64)
    src = np.linalg.norm(rows[1] - 2 * rows[0] + rows[-1], axis=-1)
    src[0] = src[-1] = 0.0
    return np.abs(real - src).max(axis=-1) if T else np.zeros(0)


def at_steps(profile: np.ndarray, steps) -> dict:
    """step t (output frames t - 1 -> t) -> the largest of ``profile`` over frames t - 1 and t."""
    return {int(t): float(profile[max(0, t - 1):t + 1].max()) for t in steps if 1 <= t < len(profile)}
