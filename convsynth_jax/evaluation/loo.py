"""Leave-one-out evaluation (paper Section 8): hold out one session, build each character's motion
graph from the other sessions, slide 15 s windows with a 14 s hop over the held-out audio and
synthesize both characters in each window, under one ablation condition.

Conditions (a sweep axis): ``all`` (PC + LR + HP constraints), ``no_lr``, ``no_hp``, ``none``
(no audio constraint: graph quality only).
"""
from __future__ import annotations

import hashlib
import json
import logging
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
from omegaconf import DictConfig, OmegaConf

from ..errors import ConfigError
from .windows import Window, sliding_windows, window_segments

log = logging.getLogger(__name__)

CONDITIONS = {
    "all": {"use_constraints": True, "use_lr": True, "use_hp": True},
    "no_lr": {"use_constraints": True, "use_lr": False, "use_hp": True},
    "no_hp": {"use_constraints": True, "use_lr": True, "use_hp": False},
    "none": {"use_constraints": False, "use_lr": False, "use_hp": False},
}


def condition_config(cfg: DictConfig, condition: str) -> DictConfig:
    """A copy of ``cfg`` whose ``search`` switches implement the ablation ``condition``."""
    if condition not in CONDITIONS:
        raise ConfigError(f"unknown condition {condition!r}; expected one of {sorted(CONDITIONS)}")
    c = OmegaConf.create(OmegaConf.to_container(cfg, resolve=False))
    OmegaConf.set_struct(c, False)
    for k, v in CONDITIONS[condition].items():
        c.search[k] = v
    return c


def config_hash(*parts) -> str:
    text = json.dumps([OmegaConf.to_container(p, resolve=True) if isinstance(p, DictConfig) else p
                       for p in parts], sort_keys=True, default=str)
    return hashlib.sha1(text.encode()).hexdigest()[:12]


@dataclass
class FoldGraphs:
    """Per character: the motion graph, the clip motions it indexes, and construction seconds."""

    graphs: dict = field(default_factory=dict)
    motions: dict = field(default_factory=dict)
    seconds: dict = field(default_factory=dict)
    summaries: dict = field(default_factory=dict)


def clip_name(session: str, role: str) -> str:
    """Name of one participant's recording inside a motion graph."""
    return f"{session}_{role}"


def annotate_corpus_cached(corpus, cfg, cache_dir: str | Path | None = None):
    """Annotations of every session (dict session -> role -> ParticipantAnnotation), cached on disk
    next to the corpus keyed by the annotation/feature config, since every fold reuses them."""
    import pickle

    from ..annotate.pipeline import annotate_corpus

    key = config_hash(str(Path(corpus.root).resolve()), cfg.annotate, cfg.features)
    cache = Path(cache_dir) / f"annotations_{key}.pkl" if cache_dir else None
    if cache is not None and cache.is_file():
        try:
            with open(cache, "rb") as fh:
                return pickle.load(fh)
        except Exception as e:  # a stale or foreign cache is rebuilt, never trusted
            log.warning("ignoring unreadable annotation cache %s (%s)", cache, e)
    result = annotate_corpus(corpus, cfg, progress=bool(cfg.get("progress", True)))
    result = _by_session(result)
    if cache is not None:
        from ..utils import atomic_path

        with atomic_path(cache, suffix=".pkl") as tmp:
            with open(tmp, "wb") as fh:
                pickle.dump(result, fh, protocol=pickle.HIGHEST_PROTOCOL)
    return result


def _by_session(result) -> dict:
    if isinstance(result, dict):
        return result
    out = {}
    for item in result:
        name = getattr(item, "name", None) or item[0]
        out[name] = getattr(item, "participants", None) or item[1]
    return out


def character_clips(annotations: dict, sessions: list[str], character: str) -> list:
    """(clip name, Motion, own FrameAudio, partner FrameAudio) of ``character`` in ``sessions``."""
    clips = []
    for s in sessions:
        for role, ann in annotations[s].items():
            if ann.character == character:
                clips.append((clip_name(s, role), ann.motion, ann.own, ann.partner))
    return clips


def build_fold_graphs(annotations: dict, held_out: str, cfg, cache_dir: str | Path | None = None) -> FoldGraphs:
    """Build (or load from the cache) each character's graph from every session but ``held_out``."""
    from ..graph import load_graph
    from ..graph.build import build_graph_from_clips

    sessions = [s for s in annotations if s != held_out]
    characters = sorted({a.character for s in annotations.values() for a in s.values()})
    out = FoldGraphs()
    for char in characters:
        clips = character_clips(annotations, sessions, char)
        out.motions[char] = {name: m for name, m, _, _ in clips}
        # the graph stores the clips' audio labels, so the annotation settings are part of the key
        key = config_hash(sorted(out.motions[char]), cfg.graph, cfg.features, cfg.annotate)
        cached = Path(cache_dir) / f"graph_{char}_{key}.npz" if cache_dir else None
        if cached is not None and cached.is_file():
            g = load_graph(cached)
            out.graphs[char] = g
            out.seconds[char] = float(g.meta.get("seconds", np.nan))
            continue
        t0 = time.perf_counter()
        g = build_graph_from_clips(clips, cfg)
        out.seconds[char] = time.perf_counter() - t0
        g.meta["seconds"] = out.seconds[char]
        out.graphs[char] = g
        if cached is not None:
            g.save(cached)
    return out


def _event_counts(events, own_segments, partner_segments, prefix: str) -> dict:
    """matched/total per hypothesis for one window (motion events vs audio segments)."""
    from ..stats.cooccurrence import window_matches

    out = {}
    for h, (matched, total) in window_matches(events, own_segments, partner_segments).items():
        out[f"{prefix}_{h}_matched"] = matched
        out[f"{prefix}_{h}_total"] = total
    return out


def run_fold(corpus, annotations: dict, fold: int, condition: str, cfg, out_dir: Path | None = None,
             cache_dir: str | Path | None = None, export_bvh: bool = False) -> pd.DataFrame:
    """All test cases of one fold in one condition: one row per (window, character)."""
    from ..annotate.motion import joint_speeds, segment_motion
    from ..io import save_bvh
    from ..kinematics import forward_kinematics, pose_features
    from ..search.check import check_path
    from ..synth.pipeline import synthesize_character
    from . import metrics

    names = [s.name for s in corpus.sessions]
    if not 0 <= fold < len(names):
        raise ConfigError(f"fold {fold} out of range: the corpus has {len(names)} sessions")
    held_out = names[fold]
    ccfg = condition_config(cfg, condition)
    fg = build_fold_graphs(annotations, held_out, cfg, cache_dir)
    loo = cfg.get("loo", {}) or {}
    length, hop = float(loo.get("window", 15.0)), float(loo.get("hop", 14.0))
    method = str(loo.get("method", "beam"))
    fps = float(cfg.features.fps)
    held = annotations[held_out]
    duration = min(a.motion.num_frames for a in held.values()) / fps
    windows = sliding_windows(duration, length, hop)
    max_windows = loo.get("max_windows")
    if max_windows:
        windows = windows[: int(max_windows)]
    clip_audio = {clip_name(s, r): (a.own, a.partner) for s, d in annotations.items() for r, a in d.items()}
    rows = []
    synth_windows: dict = {}  # character -> root-relative positions of each solved window
    for w in windows:
        f0, n = int(round(w.start * fps)), int(round(w.duration * fps))
        for role, ann in held.items():
            char = ann.character
            own = window_segments(ann.segments, w)
            partner = window_segments(ann.partner_segments, w)
            seed = int(cfg.seed) * 100003 + fold * 1009 + w.index * 17 + (0 if role == list(held)[0] else 1)
            row = {"fold": fold, "session": held_out, "condition": condition, "window": w.index,
                   "window_start": w.start, "window_end": w.end, "character": char, "role": role,
                   "method": method, "construction_seconds": fg.seconds.get(char, np.nan), "status": "ok"}
            try:
                res = synthesize_character(fg.graphs[char], fg.motions[char], own, partner, n, ccfg,
                                           seed=seed, method=method, chair_index=list(held).index(role))
            except Exception as e:  # recorded, never ends the sweep
                log.exception("fold %d window %d %s failed", fold, w.index, char)
                rows.append({**row, "success": False, "status": "error", "error": f"{type(e).__name__}: {e}"})
                continue
            row.update({
                "success": bool(res.success), "cost": res.cost, "search_seconds": res.search_seconds,
                "num_synthetic_transitions": res.num_synthetic_transitions,
                "constraints_total": res.constraints_total, "constraints_met": res.constraints_met,
                "failure": res.failure,
            })
            if res.success:  # the full constraint set (whatever the condition) by the independent checker
                chk = check_path(res.source_clip, res.source_frame, clip_audio, own, partner, fps,
                                 float(cfg.search.get("tolerance", 0.1)))
                row.update({"all_constraints_total": chk["total"], "all_constraints_met": chk["met"]})
                for kind in ("PC", "LR", "PH", "idle"):
                    d = [x["met"] for x in chk["details"] if x["kind"] == kind]
                    row[f"checker_{kind}_met"], row[f"checker_{kind}_total"] = int(sum(d)), len(d)
            gt_motion = ann.motion.slice(f0, f0 + n)
            gt_pos = np.asarray(forward_kinematics(gt_motion), dtype=np.float64)
            gt_events = segment_motion(joint_speeds(gt_motion, cfg), own, fps, partner, cfg)
            row.update(_event_counts(gt_events, own, partner, "gt"))
            row.update({"gt_jerk": metrics.mean_jerk(gt_pos, fps), "gt_acceleration": metrics.mean_acceleration(gt_pos, fps),
                        "gt_max_jump": float(metrics.max_frame_jump(gt_pos).max(initial=0.0))})
            if res.success and res.motion is not None:
                pos = np.asarray(forward_kinematics(res.motion), dtype=np.float64)
                synth_windows.setdefault(char, []).append(np.asarray(pose_features(res.motion).positions))
                ev = segment_motion(joint_speeds(res.motion, cfg), own, fps, partner, cfg)
                row.update(_event_counts(ev, own, partner, "synth"))
                used = np.asarray(res.transition_costs or [], dtype=np.float64)
                row.update({
                    "jerk": metrics.mean_jerk(pos, fps), "acceleration": metrics.mean_acceleration(pos, fps),
                    "speed_hellinger": metrics.speed_histogram_distance(pos, gt_pos, fps),
                    "max_jump": float(metrics.max_frame_jump(pos).max(initial=0.0)),
                    "mean_transition_cost": float(used.mean()) if used.size else 0.0,
                })
                if export_bvh and out_dir is not None:
                    save_bvh(res.motion, Path(out_dir) / "bvh" / f"{held_out}_w{w.index:02d}_{char}_{condition}.bvh")
            rows.append(row)
    out = pd.DataFrame(rows)
    if len(out):  # diversity between the windows synthesized for each character in this fold and condition
        out["diversity"] = out["character"].map(lambda c: metrics.window_diversity(synth_windows.get(c, [])))
    return out
