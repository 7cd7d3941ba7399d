"""Task ``walktalk_demo``: two characters walking (and, as a variant, jogging) side by side while
talking, driven by real speech. Writes one BVH per character and gait (``<name>_<gait>.bvh``),
``walktalk_events.csv`` (one row per spliced gesture) and ``walktalk_aar.csv`` (gaze events)."""
from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np
import pandas as pd
from omegaconf import OmegaConf

from ..errors import MissingFileError, WalkTalkError
from ..io.bvh import save_bvh
from ..utils import atomic_path
from ..walktalk.demo import DemoParams, Speaker, run_demo
from ..walktalk.evaluate import dof_limits, load_library, resolve_data_dir
from ..walktalk.gaze import AAREvent
from ..walktalk.params import params_from_dict

REPO = Path(__file__).resolve().parents[2]
log = logging.getLogger(__name__)
EVENT_COLUMNS = ["character", "gesture", "gait", "t_prep_begin", "t_stroke_peak", "t_retraction_end",
                 "utterance_peak_s", "shift_s", "contact_at_peak"]


def _resolve(path: str) -> Path:
    p = Path(path)
    if not p.is_absolute() and not p.exists():
        p = REPO / p
    return p


def speech_peaks(spec: dict, cfg) -> tuple[float, ...]:
    """Stress peaks (s, on the shared timeline) of one speaker: F0 peaks of the phonemic clauses
    found by ``convsynth_jax.annotate.audio`` in a WAV + transcript, or the ``peak`` column of a TSV;
    shifted by ``offset_s``."""
    off = float(spec.get("offset_s", 0.0))
    if spec.get("peaks_tsv"):
        path = _resolve(spec["peaks_tsv"])
        if not path.is_file():
            raise MissingFileError("peak TSV not found", path)
        df = pd.read_csv(path, sep="\t")
        if "peak" not in df.columns:
            raise WalkTalkError("peak TSV needs a 'peak' column (seconds)", path, "line 1")
        return tuple(float(x) + off for x in df["peak"])
    from ..annotate.audio import annotate_audio
    from ..io.audio import load_audio
    from ..io.transcripts import load_transcript

    wav, tr = _resolve(spec["wav"]), _resolve(spec["transcript"])
    from .common import params_of

    seg = annotate_audio(load_transcript(tr), load_audio(wav), params_of(cfg).annotate)
    return tuple(float(x) + off for x in seg.loc[seg["kind"] == "PC", "peak"])


def _pick_loops(lcs, n):
    """The n loops (different clips) whose speeds are closest, so side-by-side walkers keep pace."""
    speeds = np.array([np.linalg.norm(lc.loop.advance) / lc.loop.num_frames for lc in lcs])
    order = np.argsort(speeds)
    best = min(range(len(lcs) - n + 1), key=lambda i: speeds[order[i + n - 1]] - speeds[order[i]])
    return [lcs[k] for k in order[best:best + n]]


def _synthesized_source(t: dict, speakers: list, lib, p, own_times: bool):
    """Per speaker, the gestures cut from its character's synthesized BVH (``task.synthesized_dir``,
    the output folder of ``task=synthesize``; ``task.synthesized_characters`` one character per
    speaker, default the folder's BVHs sorted) as GestureContexts; with ``own_times`` each speaker's peaks
    become its gestures' own stroke peaks (+ offset_s, + lead_s so the nominal peak is the
    synthesized one). Returns (gestures by speaker, speakers, info for the summary)."""
    import dataclasses

    from ..walktalk.pipeline import gesture_context
    from ..walktalk.conversation_gestures import synthesized_gestures

    folder = _resolve(str(t.get("synthesized_dir") or ""))
    if not t.get("synthesized_dir") or not folder.is_dir():
        raise MissingFileError("gesture_source=synthesized needs task.synthesized_dir, the output folder of "
                               "task=synthesize", folder)
    chars = t.get("synthesized_characters") or sorted(f.stem for f in folder.glob("*.bvh"))
    if len(chars) < len(speakers):
        raise WalkTalkError(f"{len(speakers)} speakers but synthesized characters {list(chars)}", folder)
    files = {sp.name: folder / f"{c}.bvh" for sp, c in zip(speakers, chars)}
    offsets = {s["name"]: float(s.get("offset_s", 0.0)) for s in t["speakers"]}
    template = lib.gestures[0].gesture.motion if lib.gestures else None
    if template is None:
        raise WalkTalkError("gesture_source=synthesized needs one standing gesture clip of the library as the "
                            "retargeting template", where="walktalk.gesture_globs")
    pad = round(p.splice.transition_pad_s * p.fps)
    by_speaker, out_speakers, info = {}, [], {}
    duration = float(t["duration_s"])
    for sp in speakers:
        path = _resolve(str(files[sp.name]))
        if not path.is_file():
            raise MissingFileError("synthesized BVH not found", path)
        gs, starts, skipped = synthesized_gestures(path, template, lib.body, p)
        by_speaker[sp.name] = [gesture_context(g, lib.body, pad) for g in gs]
        info[sp.name] = {"file": str(path), "gestures": len(gs), "skipped": skipped}
        if own_times:
            peaks = [offsets[sp.name] + st + g.phases.peaks[0] / p.fps + p.splice.lead_s for g, st in zip(gs, starts)]
            keep = [k for k, u in enumerate(peaks) if 0 <= u <= duration]
            sp = dataclasses.replace(sp, peaks_s=tuple(peaks[k] for k in keep), gesture_at=tuple(keep),
                                     source=str(path))
        out_speakers.append(sp)
    return by_speaker, out_speakers, info


def run(cfg, out_dir: Path) -> dict:
    t = OmegaConf.to_container(cfg.task, resolve=True)
    p = params_from_dict(OmegaConf.to_container(cfg.walktalk, resolve=True))
    dp = DemoParams(duration_s=float(t["duration_s"]), spacing_cm=float(t["spacing_cm"]),
                    min_gap_s=float(t["min_gap_s"]), aar=str(t["aar"]), method=str(t["method"]),
                    include_multi_peak=bool(t["include_multi_peak"]))
    source = str(t.get("gesture_source", "library"))
    if source not in ("library", "synthesized"):
        raise WalkTalkError(f"gesture_source must be library or synthesized, got {source!r}", where="task.gesture_source")
    timing = str(t.get("synthesized_timing", "own"))
    if timing not in ("own", "speech"):
        raise WalkTalkError(f"synthesized_timing must be own or speech, got {timing!r}", where="task.synthesized_timing")
    own_times = source == "synthesized" and timing == "own"
    t0 = time.perf_counter()
    speakers = [Speaker(s["name"], () if own_times else speech_peaks(s, cfg), str(s.get("wav") or s.get("peaks_tsv")))
                for s in t["speakers"]]
    t1 = time.perf_counter()
    data_dir = resolve_data_dir(p, REPO)
    lib = load_library(p, data_dir, int(t["loop_candidates"]), 1 if source == "synthesized" else t.get("max_gestures"))
    gestures, synth_info = lib.gestures, {}
    if source == "synthesized":
        gestures, speakers, synth_info = _synthesized_source(t, speakers, lib, p, own_times)
    scripted = [AAREvent(**e) for e in (t.get("scripted_aar") or [])]
    t2 = time.perf_counter()
    rows, aar_rows, files = [], [], []
    rng = np.random.default_rng(p.seed)
    rom = dof_limits(lib, p.splice.joint_limit_percentiles)
    for gait in t["gaits"]:
        lcs = lib.loops.get(gait) or []
        if not lcs:
            raise WalkTalkError(f"no {gait} loop found", data_dir)
        if len(lcs) < len(speakers):  # e.g. the one-clip test fixtures: characters share a loop
            log.warning("%d characters but %d %s loops: loops are reused", len(speakers), len(lcs), gait)
            lcs = [lcs[i % len(lcs)] for i in range(len(speakers))]
        motions, ev, aar = run_demo(_pick_loops(lcs, len(speakers)), gestures, speakers, p, dp, rng, scripted, rom)
        for name, m in motions.items():
            save_bvh(m, out_dir / f"{name}_{gait}.bvh")
            files.append(f"{name}_{gait}.bvh")
        rows += ev
        aar_rows += [{"gait": gait, **e.__dict__} for e in aar]
    t3 = time.perf_counter()
    events = pd.DataFrame(rows, columns=EVENT_COLUMNS + ["single_peak"])
    with atomic_path(out_dir / "walktalk_events.csv") as tmp:
        events.to_csv(tmp, index=False)
    with atomic_path(out_dir / "walktalk_aar.csv") as tmp:
        pd.DataFrame(aar_rows).to_csv(tmp, index=False)
    single = events[events["single_peak"]] if len(events) else events
    return {"data_dir": str(data_dir), "files": files, "gestures_spliced": len(events),
            "utterance_peaks": {s.name: len(s.peaks_s) for s in speakers},
            "single_peak_contact_rate": float(single["contact_at_peak"].mean()) if len(single) else None,
            "shift_range_s": [float(events["shift_s"].min()), float(events["shift_s"].max())] if len(events) else None,
            "aar_events": len(aar_rows), "gesture_source": source, "synthesized": synth_info,
            "speech_seconds": t1 - t0, "load_seconds": t2 - t1,
            "synthesis_seconds": t3 - t2}
