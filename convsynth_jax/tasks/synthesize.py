"""Task ``synthesize``: motion for both characters of a conversation window.

Input: a session of the configured corpus (``task.session`` name or ``task.fold`` index, default 0)
and a window (``task.start``, ``task.duration`` seconds, default 0 and 15); optionally new audio and
transcripts per role (``task.inputs.<role>.audio`` / ``.transcript``) that replace the session's.
Graphs: ``task.graphs.<character>`` files, else built from every other session (cached).

Writes ``<character>.bvh``, ``<character>_blinks.csv``, ``<role>_input.wav`` (the input audio of the
window), ``report.json`` (path, transitions used with costs, constraints hit and missed by the
independent checker, timings) and a summary with success, search_seconds (per character),
num_synthetic_transitions, constraints_total, constraints_met and, per output frame, the source
graph state (file and frame).
"""
from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import ConfigError
from ..utils import atomic_path, write_json_atomic

log = logging.getLogger(__name__)


def run(cfg, out_dir: Path) -> dict:
    from ..annotate.audio import annotate_audio
    from ..annotate.types import FrameAudio
    from ..evaluation.loo import annotate_corpus_cached, build_fold_graphs, clip_name
    from ..evaluation.windows import Window, window_segments
    from ..graph import load_graph
    from ..io import load_audio, load_transcript, save_bvh, save_wav
    from ..search.check import check_path
    from ..synth.pipeline import synthesize_character
    from .common import open_corpus

    t0 = time.perf_counter()
    task = cfg.task
    corpus = open_corpus(cfg)
    cache = Path(cfg.cache_dir) / "loo_cache"
    ann = annotate_corpus_cached(corpus, cfg, cache)
    names = [s.name for s in corpus.sessions]
    session = task.get("session") or names[int(task.get("fold", 0))]
    if session not in ann:
        raise ConfigError(f"no session {session!r}; sessions are {names}")
    fps = float(cfg.features.fps)
    start, duration = float(task.get("start", 0.0)), float(task.get("duration", 15.0))
    held = ann[session]
    avail = min(a.motion.num_frames for a in held.values()) / fps
    if start < 0 or start + duration > avail + 1e-6:
        raise ConfigError(f"window {start}-{start + duration} s does not fit session {session!r} ({avail:.1f} s)")
    w = Window(0, start, start + duration)
    n = int(round(duration * fps))
    # input audio annotation per role: the session's, or files given in task.inputs
    inputs = task.get("inputs") or {}
    segs, audio = {}, {}
    for role, a in held.items():
        spec = inputs.get(role) if inputs else None
        if spec:
            words, aud = load_transcript(spec.transcript), load_audio(spec.audio)
            segs[role] = annotate_audio(words, aud, cfg)
            audio[role] = aud
        else:
            segs[role] = a.segments
            p = [pp for pp in corpus.session(session).participants if pp.role == role][0]
            audio[role] = p.load_audio() if p.audio_path else None
    roles = list(held)
    t_graph = time.perf_counter()
    given = task.get("graphs") or {}
    if given:
        from ..evaluation.loo import FoldGraphs

        fg = FoldGraphs()
        for char, path in given.items():
            g = load_graph(path)
            fg.graphs[char] = g
            fg.motions[char] = {}
            for cn in g.clip_names:
                s_name, role = cn.rsplit("_", 1)
                fg.motions[char][cn] = ann[s_name][role].motion
            fg.seconds[char] = 0.0
    else:
        fg = build_fold_graphs(ann, session, cfg, cache)
    graph_seconds = time.perf_counter() - t_graph
    clip_audio = {clip_name(s, r): (a.own, a.partner) for s, d in ann.items() for r, a in d.items()}
    method = str(task.get("method", "beam"))
    summary = {"session": session, "window": [start, start + duration], "method": method, "success": True,
               "search_seconds": {}, "num_synthetic_transitions": {}, "constraints_total": {}, "constraints_met": {},
               "cost": {}, "source_frames": {}, "failure": {}, "graph_seconds": graph_seconds}
    report = {"characters": {}}
    for k, role in enumerate(roles):
        a = held[role]
        char = a.character
        own = window_segments(segs[role], w)
        partner = window_segments(segs[roles[1 - k]], w)
        res = synthesize_character(fg.graphs[char], fg.motions[char], own, partner, n, cfg,
                                   seed=int(cfg.seed) + k, method=method, chair_index=k)
        summary["search_seconds"][char] = res.search_seconds
        summary["constraints_total"][char] = res.constraints_total
        if not res.success:
            summary["success"] = False
            summary["failure"][char] = res.failure
            summary["constraints_met"][char] = 0
            summary["num_synthetic_transitions"][char] = 0
            report["characters"][char] = {"success": False, "failure": res.failure}
            log.warning("%s: %s", char, res.failure)
            continue
        chk = check_path(res.source_clip, res.source_frame, clip_audio, own, partner, fps,
                         float(cfg.search.get("tolerance", 0.1)), bool(cfg.search.get("use_lr", True)),
                         bool(cfg.search.get("use_hp", True)))
        summary["constraints_total"][char] = chk["total"]
        summary["constraints_met"][char] = chk["met"]
        summary["num_synthetic_transitions"][char] = res.num_synthetic_transitions
        summary["cost"][char] = res.cost
        summary["source_frames"][char] = [[c, int(f)] for c, f in zip(res.source_clip, res.source_frame)]
        save_bvh(res.motion, out_dir / f"{char}.bvh")
        with atomic_path(out_dir / f"{char}_blinks.csv") as tmp:
            pd.DataFrame({"frame": np.arange(n), "time": np.arange(n) / fps, "blink": res.blinks}).to_csv(tmp, index=False)
        g = fg.graphs[char]
        trans = [{"frame": t + 1, "from": [res.source_clip[t], res.source_frame[t]],
                  "to": [res.source_clip[t + 1], res.source_frame[t + 1]]}
                 for t in range(n - 1) if res.source_clip[t] != res.source_clip[t + 1]
                 or res.source_frame[t + 1] != res.source_frame[t] + 1]
        report["characters"][char] = {"success": True, "role": role, "cost": res.cost, "path": [int(x) for x in res.path],
                                      "transitions": trans, "transition_costs": res.transition_costs,
                                      "checker": chk, "search_seconds": res.search_seconds,
                                      "graph": {"num_states": g.num_states, "num_edges": g.num_edges,
                                                "threshold": g.meta.get("threshold")}}
    for role in roles:
        if audio.get(role) is not None:
            aud = audio[role]
            a0, a1 = int(start * aud.sample_rate), int((start + duration) * aud.sample_rate)
            save_wav(out_dir / f"{role}_input.wav", aud.samples[a0:a1], aud.sample_rate)
    report["timings"] = {"graphs_s": graph_seconds, "total_s": time.perf_counter() - t0}
    write_json_atomic(out_dir / "report.json", report)
    return summary
