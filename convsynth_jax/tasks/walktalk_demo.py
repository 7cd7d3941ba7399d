"""Task ``walktalk_demo``: two characters walking (and, as a variant, jogging) side by side while
talking, driven by real speech. Writes one BVH per character and gait (``<name>_<gait>.bvh``),
``walktalk_events.csv`` (one row per spliced gesture) and ``walktalk_aar.csv`` (gaze events); with
``task.video`` (default) also ``walktalk_speech.wav`` (the speech of both characters on the demo's
timeline, the first speaker left, the second right) and a video, ``task.video_file`` (default
``walktalk_demo.mp4``): one panel per gait, both characters seen along the direction of travel by a camera that
follows the pair, gestures per character on a timeline underneath, the speech as its audio track.

Speech audio per speaker: its ``wav``; with ``gesture_source=synthesized``, ``synthesized_timing=own``
and no ``wav``, the input audio that ``task=synthesize`` wrote for its character (``<role>_input.wav`` in
``task.synthesized_dir``, the role read from its ``report.json``). Each recording's time 0 is placed
at the speaker's ``offset_s``, as its stress peaks or gesture times are. A speaker with neither
(a ``peaks_tsv`` alone) is silent in the video (logged)."""
from __future__ import annotations

import json
import logging
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, List, Optional

import numpy as np
import pandas as pd

from ..config import group_params, task_settings
from ..errors import MissingFileError, WalkTalkError
from ..io.bvh import save_bvh
from ..rig import RIG_JOINTS
from ..utils import atomic_path
from ..walktalk.demo import DemoParams, Speaker, run_demo
from ..walktalk.library import dof_limits, load_library, resolve_data_dir
from ..walktalk.gaze import AAREvent

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


def _synthesized_source(t: WalkTalkDemoSettings, speakers: list, lib, p, own_times: bool):
    """Per speaker, the gestures cut from its character's synthesized BVH (``task.synthesized_dir``,
    the output folder of ``task=synthesize``; ``task.synthesized_characters`` one character per
    speaker, default the folder's BVHs sorted) as GestureContexts; with ``own_times`` each speaker's peaks
    become its gestures' own stroke peaks (+ offset_s, + lead_s so the nominal peak is the
    synthesized one). Returns (gestures by speaker, speakers, info for the summary)."""
    import dataclasses

    from ..walktalk.pipeline import gesture_context
    from ..walktalk.conversation_gestures import synthesized_gestures

    folder = _resolve(t.synthesized_dir)
    if not t.synthesized_dir or not folder.is_dir():
        raise MissingFileError("gesture_source=synthesized needs task.synthesized_dir, the output folder of "
                               "task=synthesize", folder)
    chars = t.synthesized_characters or sorted(f.stem for f in folder.glob("*.bvh"))
    if len(chars) < len(speakers):
        raise WalkTalkError(f"{len(speakers)} speakers but synthesized characters {list(chars)}", folder)
    files = {sp.name: folder / f"{c}.bvh" for sp, c in zip(speakers, chars)}
    offsets = {s["name"]: float(s.get("offset_s", 0.0)) for s in t.speakers}
    template = lib.gestures[0].gesture.motion if lib.gestures else None
    if template is None:
        raise WalkTalkError("gesture_source=synthesized needs one standing gesture clip of the library as the "
                            "retargeting template", where="walktalk.gesture_globs")
    pad = round(p.splice.transition_pad_s * p.fps)
    by_speaker, out_speakers, info = {}, [], {}
    duration = float(t.duration_s)
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


def _video_path(t: WalkTalkDemoSettings, out_dir: Path) -> Path | None:
    """The video's path (``task.video_file``, relative to the output folder), checked writable
    before any work is done; None when ``task.video`` is off."""
    if not t.video:
        return None
    if len(t.speakers) != 2:
        raise WalkTalkError(f"the video carries two speakers' audio, got {len(t.speakers)} speakers "
                            "(task.video=false writes the BVHs alone)", where="task.speakers")
    path = Path(t.video_file or "walktalk_demo.mp4")
    path = path if path.is_absolute() else out_dir / path
    if path.suffix.lower() != ".mp4":
        raise WalkTalkError(f"the video is written as MP4, got {path.name!r}", path, "task.video_file")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=path.parent, prefix=f".{path.name}.", suffix=".probe"):
            pass
    except OSError as e:
        raise WalkTalkError(f"cannot write the demo video there ({e.strerror or e})", path, "task.video_file") from None
    return path


def _speaker_audio(spec: dict, synthesized_dir: str | None, character: str | None):
    """The speaker's speech recording (io.audio.Audio) or None; see the module docstring."""
    from ..io.audio import load_audio

    if spec.get("wav"):
        return load_audio(_resolve(str(spec["wav"])))   # MissingFileError names the file
    if not synthesized_dir:
        return None
    folder, char = _resolve(synthesized_dir), character
    report = folder / "report.json"
    if not report.is_file():
        raise MissingFileError("the synthesized conversation's report.json (the character's role, for its input "
                               "audio) is missing; give the speaker a wav", report)
    entry = json.loads(report.read_text()).get("characters", {}).get(char) or {}
    if "role" not in entry:
        raise WalkTalkError(f"report.json has no role for character {char!r}", report, f"characters.{char}")
    wav = folder / f"{entry['role']}_input.wav"
    if not wav.is_file():
        raise MissingFileError(f"input audio of character {char!r} (role {entry['role']}) not found", wav)
    return load_audio(wav)


def _follow_pair(bodies, hips: list[int]):
    """Bodies with the camera on the pair: every frame shifted on the ground so the mean of the
    characters' hips (``hips``: the hips joint per body) is at the origin; the walkers stay in view
    and the locomotion shows in the legs. Joints above the hips (bandai2's static ``joint_Root``, left
    behind at the start of the walk) are drawn at the hips."""
    from dataclasses import replace

    centre = np.mean([b.positions[:, h] for b, h in zip(bodies, hips)], axis=0)
    shift = np.zeros_like(centre)
    shift[:, [0, 2]] = centre[:, [0, 2]]
    out = []
    for b, h in zip(bodies, hips):
        pos = b.positions - shift[:, None, :]
        j = b.parents[h]
        while j >= 0:
            pos[:, j] = pos[:, h]
            j = b.parents[j]
        out.append(replace(b, positions=pos))
    return tuple(out)


def write_demo_video(motions_by_gait: dict, events: pd.DataFrame, names: list[str], fps: float, path: Path,
                     wav: Path, video_fps: float, dpi: int) -> Path:
    """One panel per gait (the characters' motions, in ``names`` order, seen from ahead of the walk)
    over a timeline of each character's gestures per gait (t_Pb..t_Re), with ``wav`` as the audio
    track. ``dpi``: the size, 80 draws 400 x 360 pixels per panel."""
    from ..render import Panel, Timeline, body_from_motion, render_video

    panels = []
    for gait, motions in motions_by_gait.items():
        bodies = tuple(body_from_motion(motions[n], n, k) for k, n in enumerate(names))
        hips = [motions[n].skeleton.find(*RIG_JOINTS["hips"]) for n in names]
        panels.append(Panel(gait, _follow_pair(bodies, hips)))
    timelines = []
    for gait in motions_by_gait:
        for k, n in enumerate(names):
            ev = events[(events["gait"] == gait) & (events["character"] == n)] if len(events) else events
            timelines.append(Timeline(f"{n}, {gait}", pd.DataFrame(
                {"kind": ["G"] * len(ev), "start": list(ev.get("t_prep_begin", [])), "end": list(ev.get("t_retraction_end", []))}),
                color=k))
    scale = dpi / 80.0
    try:
        # X, across the pair (demo.place_character), is screen right before the yaw: the camera looks along the walk
        return render_video(panels, timelines, fps, path, audio=wav, render_fps=video_fps,
                            panel_width=int(round(400 * scale)), panel_height=int(round(360 * scale)), across=(1.0, 0.0, 0.0))
    except (OSError, RuntimeError) as e:   # ffmpeg's own failures (imageio-ffmpeg raises these)
        raise WalkTalkError(f"writing the demo video failed: {e}", path) from None


@dataclass(frozen=True)
class WalkTalkDemoSettings:
    """``conf/task/walktalk_demo.yaml``."""

    name: str = "walktalk_demo"
    gaits: List[str] = field(default_factory=lambda: ["walk", "jog"])  # one pair of characters per gait
    duration_s: float = 60.0
    spacing_cm: float = 100.0           # lateral distance between the two walkers (ours)
    min_gap_s: float = 0.2              # least gap between consecutive gestures of a character (ours)
    aar: str = "inferred"               # inferred | random | scripted | statistics
    scripted_aar: List[Dict[str, Any]] = field(default_factory=list)  # aar=scripted: [{addresser, addressee, t_begin, t_full, t_release, t_end}]
    method: str = "stylized+synced"
    include_multi_peak: bool = True     # also use multi-peak gestures (never realigned)
    loop_candidates: int = 6            # loops per gait to choose the closest-speed pair from
    max_gestures: Optional[int] = 60    # gesture clips loaded, spread across kinds (None = all)
    gesture_source: str = "library"     # library | synthesized
    synthesized_dir: str = ""           # the output folder of task=synthesize
    synthesized_characters: Optional[List[str]] = None  # one character per speaker (None: the folder's BVHs, sorted)
    synthesized_timing: str = "own"     # own | speech
    speakers: List[Dict[str, Any]] = field(default_factory=list)  # {name, wav, transcript, offset_s} (or peaks_tsv)
    video: bool = True                  # also write the rendered video with both speakers' speech
    video_file: str = "walktalk_demo.mp4"   # relative to the output folder
    video_fps: float = 10.0             # frames drawn per second of motion (the motion is 30 fps)
    video_dpi: int = 80                 # the video's size: 80 draws 400 x 360 pixels per gait


def run(cfg, out_dir: Path) -> dict:
    t = task_settings(cfg)
    video_path = _video_path(t, out_dir)
    p = group_params(cfg, "walktalk")
    dp = DemoParams(duration_s=t.duration_s, spacing_cm=t.spacing_cm, min_gap_s=t.min_gap_s, aar=t.aar,
                    method=t.method, include_multi_peak=t.include_multi_peak)
    source = t.gesture_source
    if source not in ("library", "synthesized"):
        raise WalkTalkError(f"gesture_source must be library or synthesized, got {source!r}", where="task.gesture_source")
    timing = t.synthesized_timing
    if timing not in ("own", "speech"):
        raise WalkTalkError(f"synthesized_timing must be own or speech, got {timing!r}", where="task.synthesized_timing")
    own_times = source == "synthesized" and timing == "own"
    t0 = time.perf_counter()
    speakers = [Speaker(s["name"], () if own_times else speech_peaks(s, cfg), str(s.get("wav") or s.get("peaks_tsv")))
                for s in t.speakers]
    t1 = time.perf_counter()
    data_dir = resolve_data_dir(p, REPO)
    lib = load_library(p, data_dir, t.loop_candidates, 1 if source == "synthesized" else t.max_gestures)
    gestures, synth_info = lib.gestures, {}
    if source == "synthesized":
        gestures, speakers, synth_info = _synthesized_source(t, speakers, lib, p, own_times)
    scripted = [AAREvent(**e) for e in t.scripted_aar]
    audio = {}
    if video_path is not None:   # read before any work, so a missing recording stops the run here
        for spec, sp in zip(t.speakers, speakers):
            char = Path(synth_info[sp.name]["file"]).stem if sp.name in synth_info else None
            audio[sp.name] = _speaker_audio(spec, t.synthesized_dir if own_times else None, char)
            if audio[sp.name] is None:
                log.warning("speaker %s has no speech recording (wav): silent in the video", sp.name)
    t2 = time.perf_counter()
    rows, aar_rows, files, by_gait = [], [], [], {}
    rng = np.random.default_rng(p.seed)
    rom = dof_limits(lib, p.splice.joint_limit_percentiles)
    for gait in t.gaits:
        lcs = lib.loops.get(gait) or []
        if not lcs:
            raise WalkTalkError(f"no {gait} loop found", data_dir)
        if len(lcs) < len(speakers):  # e.g. the one-clip test fixtures: characters share a loop
            log.warning("%d characters but %d %s loops: loops are reused", len(speakers), len(lcs), gait)
            lcs = [lcs[i % len(lcs)] for i in range(len(speakers))]
        motions, ev, aar = run_demo(_pick_loops(lcs, len(speakers)), gestures, speakers, p, dp, rng, scripted, rom)
        by_gait[gait] = motions
        for name, m in motions.items():
            save_bvh(m, out_dir / f"{name}_{gait}.bvh")
            files.append(f"{name}_{gait}.bvh")
        rows += ev
        aar_rows += [{"gait": gait, **e.__dict__} for e in aar]
    t3 = time.perf_counter()
    events = pd.DataFrame(rows, columns=EVENT_COLUMNS + ["single_peak", "contact_alt_at_peak", "contact_at_nominal",
                                                        "contact_alt_at_nominal"])
    with atomic_path(out_dir / "walktalk_events.csv") as tmp:
        events.to_csv(tmp, index=False)
    with atomic_path(out_dir / "walktalk_aar.csv") as tmp:
        pd.DataFrame(aar_rows).to_csv(tmp, index=False)
    video = None
    if video_path is not None:
        from .converse import write_stereo

        names = [sp.name for sp in speakers]
        wav = write_stereo(out_dir / "walktalk_speech.wav", audio[names[0]], audio[names[1]], dp.duration_s,
                           offsets_s=[float(s.get("offset_s", 0.0)) for s in t.speakers])
        video = write_demo_video(by_gait, events, names, p.fps, video_path, wav, t.video_fps, t.video_dpi)
    t4 = time.perf_counter()
    single = events[events["single_peak"]] if len(events) else events
    return {"data_dir": str(data_dir), "files": files, "gestures_spliced": len(events),
            "utterance_peaks": {s.name: len(s.peaks_s) for s in speakers},
            "single_peak_contact_rate": float(single["contact_at_peak"].mean()) if len(single) else None,
            # the same by the second reading of the phases, and both at the nominal (naive,
            # unsynchronized) peak; per gait in contact_by_gait
            "single_peak_contact_alt_rate": float(single["contact_alt_at_peak"].mean()) if len(single) else None,
            "single_peak_contact_rate_naive": float(single["contact_at_nominal"].mean()) if len(single) else None,
            "single_peak_contact_alt_rate_naive": float(single["contact_alt_at_nominal"].mean()) if len(single) else None,
            "contact_by_gait": {g: {"single_peak": int(len(d)), **{c: float(d[c].mean()) for c in (
                "contact_at_peak", "contact_alt_at_peak", "contact_at_nominal", "contact_alt_at_nominal")}}
                for g, d in single.groupby("gait")} if len(single) else {},
            "shift_range_s": [float(events["shift_s"].min()), float(events["shift_s"].max())] if len(events) else None,
            "aar_events": len(aar_rows), "gesture_source": source, "synthesized": synth_info,
            "speech_seconds": t1 - t0, "load_seconds": t2 - t1,
            "synthesis_seconds": t3 - t2, "video_seconds": t4 - t3,
            "video": None if video is None else {"file": str(video), "audio": "walktalk_speech.wav",
                                                 "speakers_with_audio": [n for n, a in audio.items() if a is not None]}}
