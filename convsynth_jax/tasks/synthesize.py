"""Task ``synthesize``: motion for both characters of a conversation window, by the configured system.

Input: a session of the configured corpus (``task.session`` name or ``task.fold`` index, default 0)
and a window (``task.start``, ``task.duration`` seconds, default 0 and 15); optionally new audio and
transcripts per role (``task.inputs.<role>.audio`` / ``.transcript``) that replace the session's.
Models: fitted on every other session (cached), or for the motion graph ``task.graphs.<character>``
files. ``task.condition`` (default ``all``) is one of the system's conditions. The seed is derived
as in ``task=loo`` (base seed, fold = session index, condition, session, window start frame, role
index), so the same window gives the same motion in both tasks.

Writes ``<character>.bvh``, ``<character>_blinks.csv`` (when the system makes blinks),
``<role>_input.wav`` (the input audio of the window), ``report.json`` (per character: success,
best_effort (``search.on_failure=best_effort``), the retiming warp where there is one, constraints hit
and missed by the independent checker where the system reports per-frame provenance,
transitions used with costs, timings; ``segments``: each character's audio labels in the window)
and a summary with success, search_seconds (per character,
wall time), synthesis_cpu_seconds (per character: CPU time of the process, all threads, for search
and realization; read beside the wall time on a loaded machine), num_synthetic_transitions,
constraints_total, constraints_met and, per output frame, the source clip and frame.
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Dict, Optional

import numpy as np
import pandas as pd

from ..errors import ConfigError
from ..utils import atomic_path, write_json_atomic

log = logging.getLogger(__name__)


def label_rows(segments) -> list:
    """Audio segments as JSON rows {kind, start, end} (seconds)."""
    if segments is None or len(segments) == 0:
        return []
    return [{"kind": str(r.kind), "start": float(r.start), "end": float(r.end)} for r in segments.itertuples(index=False)]


def _given_graphs(given, ann, system):
    """Motion-graph models from graph files (``task.graphs.<character>=FILE``)."""
    from ..graph import load_graph
    out = {}
    for char, path in given.items():
        g = load_graph(path)
        motions, labels = {}, {}
        for cn in g.clip_names:
            s_name, role = cn.rsplit("_", 1)
            if s_name not in ann or role not in ann[s_name]:
                raise ConfigError(f"graph {path}: clip {cn!r} is not a recording of the configured corpus")
            a = ann[s_name][role]
            motions[cn], labels[cn] = a.motion, (a.own, a.partner)
        out[char] = system.graph_model(g, motions, 0.0, labels)   # with the configured penalties
    system.prepare(out)
    return out


@dataclass(frozen=True)
class InputFiles:
    """New speech for one role of ``task=synthesize``: a WAV and its word-level transcript."""

    audio: str
    transcript: str


@dataclass(frozen=True)
class SynthesizeSettings:
    """``conf/task/synthesize.yaml``."""

    name: str = "synthesize"
    fold: int = 0                       # the session by index (when ``session`` is None)
    session: Optional[str] = None
    start: float = 0.0                  # seconds
    duration: float = 15.0              # seconds
    condition: str = "all"              # one of the system's conditions
    graphs: Dict[str, str] = field(default_factory=dict)  # motion graph: character -> graph file
    inputs: Dict[str, InputFiles] = field(default_factory=dict)  # role -> {audio, transcript} replacing the session's


def run(cfg, out_dir: Path) -> dict:
    from ..annotate.audio import annotate_audio
    from ..config import task_settings
    from ..evaluation.loo import fit_fold, window_input
    from ..evaluation.windows import Window, window_segments
    from ..io import load_audio, load_transcript, save_bvh, save_wav
    from ..search.check import check_path
    from ..seeding import derive_seed
    from ..systems.motion_graph import clip_name
    from .common import annotated_corpus, cache_dir, make_configured_system, params_of

    t0 = time.perf_counter()
    task = task_settings(cfg)
    params = params_of(cfg)
    system = make_configured_system(params)
    condition = task.condition or "all"
    # the condition's own constraint switches (e.g. no_lr turns LR off): the checker counts what the search
    # was asked to meet, not the global search settings
    cond_opts = system.condition_options(condition)
    check_lr = bool(cond_opts.get("use_lr", params.search.use_lr))
    check_hp = bool(cond_opts.get("use_hp", params.search.use_hp))
    corpus, ann = annotated_corpus(params)
    names = list(ann)
    session = task.session or names[task.fold]
    if session not in ann:
        raise ConfigError(f"no session {session!r}; sessions are {names}")
    fold = names.index(session)
    fps = params.fps
    start, duration = task.start, task.duration
    held = ann[session]
    avail = min(a.motion.num_frames for a in held.values()) / fps
    if start < 0 or start + duration > avail + 1e-6:
        raise ConfigError(f"window {start}-{start + duration} s does not fit session {session!r} ({avail:.1f} s)")
    w = Window(0, start, start + duration)
    f0, n = int(round(start * fps)), int(round(duration * fps))
    # input audio annotation per role: the session's, or files given in task.inputs
    inputs = task.inputs
    segs, audio = {}, {}
    for role, a in held.items():
        spec = inputs.get(role) if inputs else None
        if spec:
            words, aud = load_transcript(spec.transcript), load_audio(spec.audio)
            segs[role] = annotate_audio(words, aud, params.annotate)
            audio[role] = aud
        else:
            segs[role] = a.segments
            p = [pp for pp in corpus.session(session).participants if pp.role == role][0]
            audio[role] = p.load_audio() if p.audio_path else None
    roles = list(held)
    t_fit = time.perf_counter()
    given = task.graphs
    fitted = _given_graphs(given, ann, system) if given else fit_fold(system, ann, session, condition, cache_dir(params))
    fit_seconds = time.perf_counter() - t_fit
    clip_audio = {clip_name(s, r): (a.own, a.partner) for s, d in ann.items() for r, a in d.items()}
    summary = {"system": system.name, "session": session, "window": [start, start + duration], "condition": condition,
               "search_method": params.search.method, "success": True, "search_seconds": {}, "synthesis_cpu_seconds": {},
               "num_synthetic_transitions": {}, "constraints_total": {}, "constraints_met": {}, "cost": {},
               "source_frames": {}, "failure": {}, "graph_seconds": fit_seconds}
    report = {"characters": {}}
    for k, role in enumerate(roles):
        char = held[role].character
        seed = derive_seed(params.seed, fold=fold, condition=condition, session=session, window_frame=f0, role_index=k)
        win = window_input(held, role, w, fps, seed, with_audio=system.needs_audio,
                           own_segments=segs[role], partner_segments=segs[roles[1 - k]])
        cpu = time.process_time()
        res = system.synthesize(fitted[char], win, condition)
        summary["synthesis_cpu_seconds"][char] = time.process_time() - cpu
        summary["search_seconds"][char] = res.seconds
        summary["constraints_total"][char] = res.constraints_total
        if not res.success:
            summary["success"] = False
            summary["failure"][char] = res.failure
            summary["constraints_met"][char] = 0
            summary["num_synthetic_transitions"][char] = 0
            report["characters"][char] = {"success": False, "failure": res.failure, "seed": seed}
            log.warning("%s: %s", char, res.failure)
            continue
        entry = {"success": True, "role": role, "seed": seed, "search_seconds": res.seconds,
                 **{k2: v for k2, v in res.diagnostics.items() if np.isscalar(v)}}
        summary["constraints_met"][char] = res.constraints_met
        summary["num_synthetic_transitions"][char] = len(res.synthetic_at or [])
        summary["cost"][char] = res.diagnostics.get("cost")
        if res.source_clip is not None:
            summary["source_frames"][char] = [[c, int(f)] for c, f in zip(res.source_clip, res.source_frame)]
            chk = check_path(list(res.source_clip), [int(f) for f in res.source_frame], clip_audio, win.own_segments,
                             win.partner_segments, fps, params.search.tolerance, check_lr,
                             check_hp, matching=params.search.matching, warp=res.diagnostics.get("warp"))
            summary["constraints_total"][char] = chk["total"]
            summary["constraints_met"][char] = chk["met"]
            sc, sf = res.source_clip, res.source_frame
            entry["transitions"] = [{"frame": t, "from": [sc[t - 1], int(sf[t - 1])], "to": [sc[t], int(sf[t])]}
                                    for t in (res.synthetic_at or [])]
            entry["transition_costs"] = res.diagnostics.get("transition_costs")
            entry["checker"] = chk
            warp = res.diagnostics.get("warp")
            if warp is not None:   # retiming (ours): output frame knots -> path frame knots
                entry["warp"] = {"output_frames": [float(x) for x in warp[0]], "path_frames": [float(x) for x in warp[1]]}
        model = fitted[char]
        g = getattr(model, "graph", None)
        if g is not None:
            entry["path"] = [int(x) for x in res.diagnostics.get("path", [])]
            entry["graph"] = {"num_states": g.num_states, "num_edges": g.num_edges, "threshold": g.meta.get("threshold")}
        report["characters"][char] = entry
        save_bvh(res.motion, out_dir / f"{char}.bvh")
        blinks = res.diagnostics.get("blinks")
        if blinks is not None:
            with atomic_path(out_dir / f"{char}_blinks.csv") as tmp:
                pd.DataFrame({"frame": np.arange(n), "time": np.arange(n) / fps, "blink": blinks}).to_csv(tmp, index=False)
    for role in roles:
        if audio.get(role) is not None:
            aud = audio[role]
            a0, a1 = int(start * aud.sample_rate), int((start + duration) * aud.sample_rate)
            save_wav(out_dir / f"{role}_input.wav", aud.samples[a0:a1], aud.sample_rate)
    # the window's audio labels per character (seconds from the window start; task=view draws them)
    report["segments"] = {held[role].character: label_rows(window_segments(segs[role], w)) for role in roles}
    report["timings"] = {"fit_s": fit_seconds, "total_s": time.perf_counter() - t0}
    write_json_atomic(out_dir / "report.json", report)
    return summary
