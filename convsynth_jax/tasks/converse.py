"""Task ``converse``: a whole conversation of new speech in, both characters' body motion out.

Input: character A's and B's speech as two WAV files (``task.audio_a``, ``task.audio_b``) or one
stereo WAV (``task.stereo``: channel 0 is A, 1 is B; ``task.channel_a``/``channel_b`` choose others), each
with a transcript (``task.transcript_a``, ``task.transcript_b``: any format :func:`convsynth_jax.io.load_transcript`
reads; rows of several words are aligned to the audio, and a speaker without one has its words
recognized offline, :mod:`convsynth_jax.io.recognize`), of any length.
The audio is annotated as the corpus is (phonemic clauses with F0 peaks, listener responses,
hesitations), cut into windows that are searched one after the other, each continuing the previous
one's path through the character's motion graph, and the whole path is realized at once
(:mod:`convsynth_jax.synth.chain`: no seam at window boundaries).

Models: each character's motion graph fitted on every session of the configured corpus (cached on
disk under ``${cache_dir}/loo_cache``, keyed by the clips and the graph, feature and annotation
parameters), or graph files of ``task=build_graph`` (``task.graphs=DIR`` holding
``graph_<character>.npz``, or ``task.graphs.<character>=FILE``).

Writes ``A.bvh`` and ``B.bvh`` (the whole input duration at the graph's frame rate),
``A_blinks.csv``/``B_blinks.csv``, ``conversation.wav`` (A left, B right), ``conversation.mp4``
(both characters drawn by :mod:`convsynth_jax.render` over the label timeline, the audio muxed
in; ``task.video=false`` skips it),
``report.json`` and ``report.md``: the windows (frames, seconds, status, search time), the
constraints per window and in total, by kind, as the independent checker
(:mod:`convsynth_jax.search.check`) confirms them from the path's source frames, and timings. A
window without a path (after moving its start back by ``task.backoff_s``) fails the task with an
error naming the window and its time span, after the report is written, unless
``search.on_failure=best_effort`` (where the search parameters have it) keeps the search's best path.
"""
from __future__ import annotations

import logging
import resource
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, List, Optional

import numpy as np
import pandas as pd

from ..annotate.kinds import constraint_kinds
from ..errors import AudioFormatError, ConfigError, ConvSynthError, MissingFileError, SearchFailure, TranscriptFormatError
from ..utils import atomic_path, write_json_atomic

log = logging.getLogger(__name__)


def kind_names() -> tuple:
    """The constraint kinds' names in report order (the registry's, annotate/kinds.py)."""
    return tuple(k.name for k in constraint_kinds())


@dataclass(frozen=True)
class ConverseParams:
    """``conf/task/converse.yaml`` (validated when the task starts)."""

    name: str = "converse"
    audio_a: Optional[str] = None        # WAV of character A (mono, or channel 0 is used)
    audio_b: Optional[str] = None        # WAV of character B
    stereo: Optional[str] = None         # instead of audio_a/audio_b: one WAV, channel 0 = A, 1 = B
    transcript_a: Optional[str] = None   # transcript of A (TextGrid, tsv, csv, json, srt, vtt; none: recognized)
    transcript_b: Optional[str] = None   # of B (none: recognized from B's audio)
    tier: str = "words"                  # TextGrid tier holding the words (both speakers, unless tier_a/tier_b)
    tier_a: Optional[str] = None         # A's TextGrid tier (null: task.tier)
    tier_b: Optional[str] = None         # B's TextGrid tier (null: task.tier)
    channel_a: Optional[int] = None      # A's channel of a multichannel file (null: 0)
    channel_b: Optional[int] = None      # B's channel (null: 0 of audio_b, 1 of stereo)
    # corpus characters playing A and B (null: the roles of the corpus's first session, in order)
    characters: Optional[List[str]] = None
    condition: str = "all"               # one of the system's conditions (conf/system/<name>.yaml)
    graphs: Any = None                   # null: fit on the whole corpus (cached); DIR of task=build_graph; or {character: FILE}
    window_s: float = 120.0              # searched in one search (inputs up to window_s + min_last_s: one search)
    hop_s: float = 110.0                 # kept per window of a longer input; the rest is a look-ahead horizon
    snap_s: float = 5.0                  # a cut may move back this far to a frame where nobody speaks
    min_last_s: float = 30.0             # the last window takes the rest when it is at most window_s + this
    backoff_s: List[float] = field(default_factory=lambda: [2.0, 5.0])   # a failed window starts this much earlier
    chaining: str = "graph"              # graph (continuous) | independent (the control: a seam at every cut)
    video: bool = True                   # write conversation.mp4
    video_fps: float = 10.0              # frames per second drawn in the video
    video_dpi: int = 80                  # the video's size: 80 draws 640 x 360 pixels of bodies (scales with it)
    parallel_characters: bool = True     # search and realize A and B side by side in two threads (same bytes)
    progress_s: float = 10.0             # a log line every this many seconds while the searches run (0: none)


# ----------------------------------------------------------------------------------------------- inputs
@dataclass
class SpeakerInput:
    name: str              # "A" or "B"
    audio: Any             # io.audio.Audio (mono)
    words: pd.DataFrame
    audio_file: str
    transcript_file: str
    words_source: str = "transcript"   # transcript | aligned (phrases aligned to the audio) | recognized | none
    channel: Optional[int] = None      # the channel of a multichannel file (None: a mono file)


def _require(value, key: str) -> str:
    if not value:
        raise ConfigError(f"task=converse needs task.{key}=FILE (or task.stereo=FILE for both channels)"
                          if key.startswith("audio") else f"task=converse needs task.{key}=FILE")
    return str(value)


def _empty_words() -> pd.DataFrame:
    return pd.DataFrame({"start": pd.Series(dtype=float), "end": pd.Series(dtype=float), "word": pd.Series(dtype=str)})


def _channel_of(audio, who: str, chosen: Optional[int], default: int, stereo: bool):
    """Speaker ``who``'s mono channel of ``audio``: ``task.channel_<who>`` if set, else ``default``; a
    log line says which channels a multichannel file loses (or that a mono file serves both)."""
    key = f"task.channel_{who.lower()}"
    n = audio.num_channels
    c = default if chosen is None else int(chosen)
    if not 0 <= c < n:
        raise AudioFormatError(f"channel {c} requested for speaker {who} ({key}), the file has {n} channel(s): "
                               f"set {key} to one of 0..{n - 1}", audio.path)
    if n == 1:
        return audio, None
    if not stereo:
        others = [k for k in range(n) if k != c]
        log.warning("speaker %s: %s has %d channels; channel %d is used, channel(s) %s dropped (set %s to choose "
                    "another)", who, audio.path, n, c, others, key)
    else:
        log.info("speaker %s: channel %d of %s (%d channels)", who, c, audio.path, n)
    return audio.channel(c), c


def load_inputs(p: ConverseParams, recognize: bool = True) -> tuple[SpeakerInput, SpeakerInput, float]:
    """(A, B, duration in seconds): both channels' audio and words, checked against each other. Without
    ``audio_b`` and ``transcript_b`` (and no ``stereo``), B is silent for the whole of A's speech. A
    speaker without a transcript has its words recognized from its audio (:mod:`convsynth_jax.io.recognize`),
    unless ``recognize`` is false (a system that reads the audio alone): then it has no words."""
    from ..io import load_audio

    if p.stereo:
        if p.audio_a or p.audio_b:
            raise ConfigError("give either task.stereo or task.audio_a/task.audio_b, not both")
        st = load_audio(p.stereo)
        if st.num_channels < 2 and p.channel_a is None and p.channel_b is None:
            raise AudioFormatError(f"task.stereo needs two channels (0 = A, 1 = B), the file has {st.num_channels} "
                                   "(give a mono file as task.audio_a)", p.stereo)
        chans = [_channel_of(st, "A", p.channel_a, 0, True), _channel_of(st, "B", p.channel_b, 1, True)]
        if chans[0][1] == chans[1][1]:
            log.warning("speakers A and B both get channel %s of %s", chans[0][1], p.stereo)
        auds, files = [c[0] for c in chans], [str(p.stereo)] * 2
        ch_idx = [c[1] for c in chans]
    elif not p.audio_b and not p.transcript_b:
        # one speaker's speech alone: B listens in silence for the whole of it
        a, ca = _channel_of(load_audio(_require(p.audio_a, "audio_a")), "A", p.channel_a, 0, False)
        silent = type(a)(np.zeros(a.num_samples, np.float32), a.sample_rate, "")
        log.info("no task.audio_b or task.transcript_b: B is silent for the whole conversation (%.2f s)", a.duration)
        return (_speaker("A", a, str(p.audio_a), p.transcript_a, p, ca, recognize),
                SpeakerInput("B", silent, _empty_words(), "(silent)", "(none)", "none"), a.duration)
    else:
        files = [_require(p.audio_a, "audio_a"), _require(p.audio_b, "audio_b")]
        auds, ch_idx = [], []
        for who, f, c in zip("AB", files, (p.channel_a, p.channel_b)):
            a, k = _channel_of(load_audio(f), who, c, 0, False)
            auds.append(a)
            ch_idx.append(k)
    trs = [p.transcript_a, p.transcript_b]
    out = [_speaker(name, a, f, tf, p, c, recognize) for name, a, f, tf, c in zip("AB", auds, files, trs, ch_idx)]
    duration = max(a.duration for a in auds)
    if abs(auds[0].duration - auds[1].duration) > 0.1:
        log.warning("A's audio lasts %.2f s, B's %.2f s: the conversation lasts %.2f s (the shorter is silent after "
                    "its end)", auds[0].duration, auds[1].duration, duration)
    return out[0], out[1], duration


def tier_of(p: ConverseParams, who: str) -> str:
    """The TextGrid tier of speaker ``who``: ``task.tier_a``/``task.tier_b``, else ``task.tier``."""
    own = p.tier_a if who == "A" else p.tier_b
    return str(own) if own else str(p.tier)


def _speaker(name: str, a, f: str, tf: Optional[str], p: ConverseParams, channel: Optional[int] = None,
             recognize: bool = True) -> SpeakerInput:
    """One speaker's input: the words of ``tf`` (phrases aligned to the audio; none: recognized from the
    audio), none of which may end after the audio ``a`` (file ``f``)."""
    from ..io import load_transcript
    from ..io.recognize import align_phrases, recognize_words
    from ..io.transcripts import phrase_rows

    x = name.lower()
    where = f"{f}" + (f" channel {channel}" if channel is not None else "")
    if not tf and not recognize:
        log.info("speaker %s: no transcript (task.transcript_%s): the system reads the audio alone, no words are "
                 "recognized (the timeline shows no labels)", name, x)
        return SpeakerInput(name, a, _empty_words(), f, "(none)", "none", channel)
    if not tf:
        t0 = time.perf_counter()
        words = recognize_words(a.samples, a.sample_rate)
        if words.empty:
            raise TranscriptFormatError(f"no words recognized in speaker {name}'s audio ({a.duration:.1f} s; is it "
                                        f"speech, and the right channel?): give a transcript, task.transcript_{x}=FILE",
                                        where)
        log.info("speaker %s: no transcript (task.transcript_%s): %d words recognized from the audio %s by the built-in "
                 "offline recognizer (PocketSphinx, US English) in %.1f s; recognition errors show as wrong labels: "
                 "correct words_%s.tsv beside the outputs and pass it back as task.transcript_%s", name, x, len(words),
                 where, time.perf_counter() - t0, name, x)
        words.attrs["path"] = "(recognized)"
        return SpeakerInput(name, a, words, f, "(recognized)", "recognized", channel)
    try:
        words = load_transcript(tf, tier=tier_of(p, name))
    except TranscriptFormatError as e:
        hint = f"task.tier_{x}" if "tier" in e.reason else f"task.transcript_{x}"
        raise TranscriptFormatError(f"{e.reason} (speaker {name}: set {hint})", e.path, e.where) from None
    source = "transcript"
    phrases = phrase_rows(words)
    if phrases:
        t0 = time.perf_counter()
        n_rows = len(words)
        words = align_phrases(words, a.samples, a.sample_rate, tf)
        source = "aligned"
        log.info("speaker %s: %d of the %d rows of %s hold several words: aligned to the audio %s, %d words "
                 "(%.1f s)", name, len(phrases), n_rows, tf, where, len(words), time.perf_counter() - t0)
    words.attrs["path"] = tf
    late = words.index[words["end"] > a.duration + 0.05]
    if len(late):
        i = int(late[0])
        raise TranscriptFormatError(f"word {words['word'].iat[i]!r} ends at {words['end'].iat[i]:.3f} s, after the "
                                    f"end of its audio {f} ({a.duration:.3f} s)", tf, f"word {i}")
    return SpeakerInput(name, a, words, f, tf, source, channel)


def annotate(sp: SpeakerInput, params) -> pd.DataFrame:
    """Audio segments of one speaker (the corpus's annotation); errors name the speaker's files."""
    from ..annotate.audio import annotate_audio

    try:
        return annotate_audio(sp.words, sp.audio, params.annotate)
    except ConvSynthError:
        raise
    except Exception as e:  # e.g. the F0 tracker on unusable samples
        raise AudioFormatError(f"cannot annotate speaker {sp.name} ({type(e).__name__}: {e}; transcript "
                               f"{sp.transcript_file})", sp.audio_file) from e


# ----------------------------------------------------------------------------------------------- models
def characters_of(p: ConverseParams, ann) -> list:
    """The corpus characters playing A and B: ``task.characters``, else the roles of the corpus's first
    session in order; a ConfigError unless they are two of the corpus's characters."""
    first = ann[next(iter(ann))]
    chars = list(p.characters) if p.characters else [a.character for a in first.values()][:2]
    known = sorted({a.character for d in ann.values() for a in d.values()})
    if len(chars) != 2 or any(c not in known for c in chars):
        raise ConfigError(f"task.characters must name two of the corpus's characters {known}, got {chars}")
    return chars


def _graph_files(given) -> dict:
    """character -> graph file from ``task.graphs`` (a folder of task=build_graph, or a mapping)."""
    if isinstance(given, (str, Path)):
        d = Path(given)
        if not d.is_dir():
            raise MissingFileError("task.graphs: no such folder (expected the output of task=build_graph)", d)
        files = {f.stem[len("graph_"):]: f for f in sorted(d.glob("graph_*.npz"))}
        if not files:
            raise MissingFileError("task.graphs: the folder holds no graph_<character>.npz", d)
        return files
    files = {str(k): Path(str(v)) for k, v in dict(given).items()}
    for f in files.values():
        if not f.is_file():
            raise MissingFileError("graph file not found", f)
    return files


def fit_models(p: ConverseParams, params, system, ann, chars) -> dict:
    from ..evaluation.loo import fit_fold
    from .common import cache_dir, graph_file_models

    if p.graphs:
        files = _graph_files(p.graphs)
        missing = [c for c in chars if c not in files]
        if missing:
            raise ConfigError(f"task.graphs has no graph of {missing} (has {sorted(files)})")
        return graph_file_models({c: files[c] for c in chars}, ann, system)
    # held_out None: every session of the corpus trains the models
    return fit_fold(system, ann, None, p.condition, cache_dir(params))


# ----------------------------------------------------------------------------------------------- checks
def kind_counts(details) -> dict:
    out = {k: {"met": 0, "total": 0} for k in kind_names()}
    for d in details:
        k = out.setdefault(d["kind"], {"met": 0, "total": 0})
        k["total"] += 1
        k["met"] += int(bool(d["met"]))
    return out


def check_character(res, own, partner, rows, clip_audio, fps: float, search) -> dict:
    """The independent checker over the whole conversation (cuts included, through the retiming warp
    where there is one), and its verdicts split by the window whose kept frames hold each constraint's
    start."""
    from ..search.check import check_path

    whole = check_path(res.source_clip, res.source_frame, clip_audio, own, partner, fps, search.tolerance,
                       search.use_lr, search.use_hp, matching=search.matching, warp=res.warp)
    per = []
    for r in rows:
        first, last = r["index"] == rows[0]["index"], r["index"] == rows[-1]["index"]
        mine = [d for d in whole["details"]
                if (first or d["start"] >= r["start"]) and (last or d["start"] < r["end"])]
        per.append({"index": r["index"], "met": int(sum(bool(d["met"]) for d in mine)), "total": len(mine),
                    "by_kind": kind_counts(mine)})
    return {"windows": per, "total": {"met": whole["met"], "total": whole["total"], "by_kind": kind_counts(whole["details"]),
                                      "missed": [d for d in whole["details"] if not d["met"]],
                                      "constraints": whole["details"]}}


def continuity(res, motions: dict) -> dict:
    """Seams: the excess acceleration (:func:`~convsynth_jax.synth.chain.excess_acceleration`) at the
    steps across cuts between windows, beside its largest value at the synthetic transitions inside
    windows and its median and 99th percentile over all frames. A seam shows as a cut far above the
    transitions; a cut played as the clip's continuation shows 0."""
    from ..synth.chain import at_steps, excess_acceleration

    # in path time (before the retiming warp), where frame t shows source_clip[t], source_frame[t]
    prof = excess_acceleration(res.path_motion if res.path_motion is not None else res.motion, motions,
                               res.source_clip, res.source_frame)
    cuts = set(res.cuts)
    inner = at_steps(prof, [t for t in res.synthetic_at if t not in cuts])
    return {"at_cuts": {str(t): v for t, v in at_steps(prof, res.cuts).items()},
            "cut_is_synthetic": {str(t): t in set(res.synthetic_at) for t in res.cuts},
            "at_synthetic_transitions_max": max(inner.values()) if inner else None,
            "median_all": float(np.median(prof)), "p99_all": float(np.percentile(prof, 99))}


# ----------------------------------------------------------------------------------------------- report
def write_report_md(path: Path, report: dict) -> None:
    lines = ["# Conversation synthesis", ""]
    inp = report["inputs"]
    lines += [f"Input: {inp['duration_s']:.2f} s ({inp['num_frames']} frames at {inp['fps']:g} fps); "
              f"A = {inp['A']['character']} ({inp['A']['audio']}, {inp['A']['transcript']}), "
              f"B = {inp['B']['character']} ({inp['B']['audio']}, {inp['B']['transcript']}).", "",
              f"Windows: {report['plan']['window_s']:g} s searched, {report['plan']['hop_s']:g} s kept, "
              f"chaining `{report['plan']['chaining']}`; motion written: **{report['success']}**; every constraint "
              f"met: **{report.get('all_constraints_met')}**.", ""]
    if report.get("failure"):
        lines += [f"**Failed:** {report['failure']}", ""]
    lines += ["| character | window | kept (s) | status | search (s) | constraints met (checker) | PC | LR | PH | idle |",
              "|---|---|---|---|---|---|---|---|---|---|"]
    for who in ("A", "B"):
        ch = report["characters"][who]
        checks = {w["index"]: w for w in ch.get("checker", {}).get("windows", [])}
        for w in ch["windows"]:
            c = checks.get(w["index"])
            kinds = ["" if c is None else f"{c['by_kind'][k]['met']}/{c['by_kind'][k]['total']}" for k in kind_names()]
            met = "" if c is None else f"{c['met']}/{c['total']}"
            lines.append(f"| {who} ({ch['character']}) | {w['index']} | {w['start_s']:.2f}-{w['end_s']:.2f} | "
                         f"{w['status']} | {w['seconds']:.2f} | {met} | " + " | ".join(kinds) + " |")
    lines += ["", "Whole conversation (the checker over the whole path, cuts included):", "",
              "| character | constraints met | PC | LR | PH | idle | synthetic transitions | excess acc. at cuts (max) "
              "| at transitions (max) | all frames (median / p99) |",
              "|---|---|---|---|---|---|---|---|---|---|"]
    for who in ("A", "B"):
        ch = report["characters"][who]
        tot = ch.get("checker", {}).get("total")
        if tot is None:
            lines.append(f"| {who} | failed: {ch.get('failure', '')} | | | | | | | | |")
            continue
        kinds = [f"{tot['by_kind'][k]['met']}/{tot['by_kind'][k]['total']}" for k in kind_names()]
        cont = ch["continuity"]
        cut = f"{max(cont['at_cuts'].values()):.3f}" if cont["at_cuts"] else "– (one window)"
        inner = cont["at_synthetic_transitions_max"]
        inner = "– (none)" if inner is None else f"{inner:.3f}"
        lines.append(f"| {who} | {tot['met']}/{tot['total']} | " + " | ".join(kinds) +
                     f" | {ch['num_synthetic_transitions']} | {cut} | {inner} | "
                     f"{cont['median_all']:.3f} / {cont['p99_all']:.3f} |")
    t = report["timings"]
    lines += ["", "Excess acceleration: the realized joint acceleration minus the source clip's own, largest joint "
              "(units per frame^2); 0 where a clip plays on, a seam would show far above the transitions.", "",
              "Timings (s): " + ", ".join(f"{k} {v:.2f}" for k, v in t.items()), ""]
    with atomic_path(path) as tmp:
        tmp.write_text("\n".join(lines))


# ----------------------------------------------------------------------------------------------- task
class _Timings:
    """Wall seconds per step of the run (``timings`` in report.json) and the task's CPU seconds: its own
    (all threads) and those of the programs it ran (ffmpeg). On a busy machine the wall times say little,
    the CPU times do."""

    def __init__(self):
        self.wall0, self.cpu0, self.child0 = time.perf_counter(), time.process_time(), self._children()
        self.steps: dict = {}

    @staticmethod
    def _children() -> float:
        kids = resource.getrusage(resource.RUSAGE_CHILDREN)
        return kids.ru_utime + kids.ru_stime

    def step(self, key: str, fn, *args, **kwargs):
        t0 = time.perf_counter()
        out = fn(*args, **kwargs)
        self.steps[key] = time.perf_counter() - t0
        return out

    def finished(self) -> dict:
        return {**self.steps, "total_s": time.perf_counter() - self.wall0, "cpu_s": time.process_time() - self.cpu0,
                "child_cpu_s": self._children() - self.child0}


@dataclass(frozen=True)
class _Setup:
    """What every step after the inputs needs: the task's and the library's parameters, the search, the
    two speakers, their audio labels, the characters, their models and the plan of windows."""

    p: Any
    params: Any
    search: Any
    speakers: tuple          # (SpeakerInput A, SpeakerInput B)
    duration: float
    seg: dict                # "A"/"B" -> audio labels
    chars: list
    models: dict
    clip_audio: dict         # corpus clip -> (own, partner) labels, for the checker
    num_frames: int
    plan: list

    @property
    def fps(self) -> float:
        return self.params.fps


def run(cfg, out_dir: Path) -> dict:
    """The conversation as a pipeline: read the speech, fit the characters' models, plan the windows,
    synthesize both characters, write motion and audio, draw the video, write the report and summary."""
    from ..config import task_settings
    from ..systems.motion_graph import MotionGraphSystem
    from .common import make_configured_system, params_of

    clock = _Timings()
    p, params = task_settings(cfg), params_of(cfg)
    system = make_configured_system(params)
    if system.converses_from_audio:
        return run_from_audio(system, p, params, out_dir)
    if not isinstance(system, MotionGraphSystem):
        raise ConfigError(f"task=converse chains motion-graph paths or asks a system that makes a conversation from "
                          f"audio alone (system=motion_graph or system=flow_matching; got {system.name!r})")
    system.condition_options(p.condition)
    search = system.search_params(p.condition)
    A, B, duration, seg = clock.step("inputs_s", read_speech, p, params, out_dir)
    ann, chars = clock.step("corpus_s", _corpus_characters, p, params)
    models = clock.step("models_s", fit_models, p, params, system, ann, chars)
    setup = plan_conversation(p, params, search, (A, B), duration, seg, chars, models, ann)
    report = report_head(setup)
    results = clock.step("synthesis_s", synthesize_characters, setup, report)
    wav = clock.step("write_s", write_motion_and_audio, setup, results, out_dir)
    video = None
    if p.video and all(r.success for r in results.values()):
        video = clock.step("video_s", draw_video, setup, results, wav, out_dir)
    failure = finish_report(report, setup, results, clock.finished(), wav, video, out_dir)
    if failure:
        raise SearchFailure(f"{failure} (report: {out_dir / 'report.md'})")
    return conversation_summary(report, setup)


def read_speech(p: ConverseParams, params, out_dir: Path):
    """(A, B, duration, audio labels per speaker): the inputs read and annotated as the corpus is. Words
    that were recognized or aligned are written beside the outputs, for the user to correct and pass back."""
    from ..io.transcripts import save_transcript_tsv

    A, B, duration = load_inputs(p)
    seg = {"A": annotate(A, params), "B": annotate(B, params)}
    for sp in (A, B):
        if sp.words_source in ("recognized", "aligned"):
            save_transcript_tsv(sp.words, out_dir / f"words_{sp.name}.tsv")
            log.info("speaker %s: %s words written to %s (task.transcript_%s=%s after correcting it)", sp.name,
                     sp.words_source, out_dir / f"words_{sp.name}.tsv", sp.name.lower(), f"words_{sp.name}.tsv")
    return A, B, duration, seg


def _corpus_characters(p: ConverseParams, params):
    from .common import annotated_corpus

    _, ann = annotated_corpus(params)
    return ann, characters_of(p, ann)


def plan_conversation(p: ConverseParams, params, search, speakers, duration: float, seg: dict, chars, models, ann) -> _Setup:
    """The windows over the whole input (boundaries snapped to quiet frames of both speakers) and the
    corpus's audio labels per clip, with everything the later steps read."""
    from ..synth.chain import plan_windows, quiet_mask
    from ..systems.motion_graph import clip_name

    fps = params.fps
    T = int(round(duration * fps))
    tol = int(round(float(search.tolerance) * fps))
    plan = plan_windows(T, fps, p.window_s, p.hop_s, p.snap_s, p.min_last_s, quiet_mask([seg["A"], seg["B"]], T, fps, tol))
    clip_audio = {clip_name(s, r): (a.own, a.partner) for s, d in ann.items() for r, a in d.items()}
    return _Setup(p, params, search, tuple(speakers), duration, seg, chars, models, clip_audio, T, plan)


def report_head(s: _Setup) -> dict:
    """report.json's inputs, plan and search, before any character is synthesized."""
    p = s.p
    return {"inputs": {"duration_s": s.duration, "num_frames": s.num_frames, "fps": s.fps,
                       **{sp.name: {"character": s.chars[k], "audio": sp.audio_file, "channel": sp.channel,
                                    "transcript": sp.transcript_file, "words": sp.words_source,
                                    "num_words": int(len(sp.words))} for k, sp in enumerate(s.speakers)}},
            "plan": {"window_s": p.window_s, "hop_s": p.hop_s, "snap_s": p.snap_s, "chaining": p.chaining,
                     "windows": [asdict(w) for w in s.plan]},
            "search": {"method": s.search.method, "matching": s.search.matching, "tolerance": s.search.tolerance,
                       "on_failure": getattr(s.search, "on_failure", None)},
            "condition": p.condition, "characters": {}, "success": True}


def converse_character(s: _Setup, k: int):
    """Character k's whole conversation and its report entry (the two characters are independent)."""
    from ..seeding import derive_seed
    from ..synth.chain import synthesize_conversation

    who, other, char, fps, p = "AB"[k], "BA"[k], s.chars[k], s.fps, s.p
    model = s.models[char]

    def seed_of(frame):
        return derive_seed(s.params.seed, fold=0, condition=p.condition, session="converse", window_frame=frame,
                           role_index=k)

    res = synthesize_conversation(model.graph, model.motions, s.seg[who], s.seg[other], s.num_frames, fps, s.plan, s.search,
                                  s.params.synth, seed_of, chair_index=k, backoff_s=p.backoff_s, chaining=p.chaining)
    entry = {"character": char, "success": res.success,
             "windows": [{**w, "start_s": w["start"] / fps, "end_s": w["end"] / fps} for w in res.windows],
             "search_seconds": float(sum(w["seconds"] for w in res.windows))}
    if res.success:
        entry["checker"] = check_character(res, s.seg[who], s.seg[other], res.windows, s.clip_audio, fps, s.search)
        entry["continuity"] = continuity(res, model.motions)
        entry["num_synthetic_transitions"] = len(res.synthetic_at)
        # output frames (after the retiming warp), where the video and the viewer show them
        entry["transitions"] = [{"frame": t} for t in res.output_frames(res.synthetic_at)]
        entry["cuts"] = res.output_frames(res.cuts)
        entry["cuts_path"] = [int(t) for t in res.cuts]      # the same cuts in path frames (continuity's keys)
        entry["cost"] = res.cost
        entry["graph"] = {"num_states": model.graph.num_states, "num_edges": model.graph.num_edges}
    else:
        entry["failure"] = res.failure
    return res, entry


def synthesize_characters(s: _Setup, report: dict) -> dict:
    """Both characters' conversations ("A"/"B" -> result), their entries put into ``report``; a failed
    character sets ``report["success"]`` false and ``report["failure"]`` to the first failure.

    The two searches and realizations run side by side (XLA and NumPy release the GIL for most of their
    work: on two cores this takes about the longer of the two, not their sum); each character's result
    does not depend on the other's, so the files are the same bytes as one by one."""
    stop, t0 = threading.Event(), time.perf_counter()

    def heartbeat():
        """Progress of long searches: a line every task.progress_s seconds (one per window follows as each ends)."""
        while not stop.wait(s.p.progress_s):
            log.info("searching: %.0f s so far (%d window(s) per character, %.0f s of input)",
                     time.perf_counter() - t0, len(s.plan), s.duration)

    beat = threading.Thread(target=heartbeat, name="progress", daemon=True) if s.p.progress_s > 0 else None
    if beat is not None:
        beat.start()
    try:
        with ThreadPoolExecutor(max_workers=2 if s.p.parallel_characters else 1, thread_name_prefix="character") as pool:
            done = [f.result() for f in [pool.submit(converse_character, s, k) for k in range(2)]]
    finally:
        stop.set()
    results, report["failure"] = {}, None
    for k, (who, (res, entry)) in enumerate(zip("AB", done)):
        results[who] = res
        if not res.success:
            report["success"] = False
            report["failure"] = report["failure"] or f"character {who} ({s.chars[k]}): {res.failure}"
            log.error("character %s (%s): %s", who, s.chars[k], res.failure)
        report["characters"][who] = entry
    return results


def write_motion_and_audio(s: _Setup, results: dict, out_dir: Path) -> Path:
    """``A.bvh``/``B.bvh`` and their blinks for each character that succeeded, and ``conversation.wav``
    (A left, B right); returns the WAV's path."""
    from ..io import save_bvh

    T, fps = s.num_frames, s.fps
    for who in "AB":
        res = results[who]
        if res.success:
            save_bvh(res.motion, out_dir / f"{who}.bvh")
            with atomic_path(out_dir / f"{who}_blinks.csv") as tmp:
                pd.DataFrame({"frame": np.arange(T), "time": np.arange(T) / fps, "blink": res.blinks}).to_csv(tmp, index=False)
    wav = out_dir / "conversation.wav"
    write_stereo(wav, s.speakers[0].audio, s.speakers[1].audio, s.duration)
    return wav


def draw_video(s: _Setup, results: dict, wav: Path, out_dir: Path) -> Path:
    """``conversation.mp4``: both characters over the label timeline, the synthetic transitions as ticks
    and the windows' spans when there are several, the WAV muxed in."""
    fps = s.fps
    ticks = {w: tuple(t / fps for t in results[w].output_frames(results[w].synthetic_at)) for w in "AB"}
    spans = [(r["start"] / fps, r["end"] / fps) for r in results["A"].windows] if len(s.plan) > 1 else None
    return render_conversation({w: results[w].motion for w in "AB"}, ticks, spans, s.seg, s.chars, fps,
                               out_dir / "conversation.mp4", wav, s.p)


def finish_report(report: dict, s: _Setup, results: dict, timings: dict, wav: Path, video, out_dir: Path):
    """report.json and report.md with the timings, the audio labels per speaker (task=view draws them),
    whether every constraint was met and the output files; returns the first failure (None without)."""
    from .synthesize import label_rows

    failure = report.pop("failure")
    report["timings"] = timings
    report["segments"] = {w: label_rows(s.seg[w]) for w in "AB"}
    report["failure"] = failure
    report["all_constraints_met"] = (not failure) and all(
        report["characters"][w]["checker"]["total"]["met"] == report["characters"][w]["checker"]["total"]["total"]
        for w in "AB")
    report["outputs"] = {"bvh": [f"{w}.bvh" for w in "AB" if results[w].success], "audio": wav.name,
                         "video": None if video is None else video.name}
    write_json_atomic(out_dir / "report.json", report)
    write_report_md(out_dir / "report.md", report)
    return failure


def conversation_summary(report: dict, s: _Setup) -> dict:
    """summary.json of a run whose characters were both synthesized, with a line per speaker in the log."""
    speakers = {w: speaker_summary(report, w, s.fps) for w in "AB"}
    for w in "AB":
        log.info("%s", speaker_line(w, speakers[w]))
    return {"success": True,   # motion was written for both characters
            "all_constraints_met": all(x["constraints"]["met"] == x["constraints"]["total"] for x in speakers.values()),
            "duration_s": s.duration, "num_frames": s.num_frames, "windows": len(s.plan),
            "characters": {w: s.chars[k] for k, w in enumerate("AB")},
            "constraints_met": {w: speakers[w]["constraints"]["met"] for w in "AB"},
            "constraints_total": {w: speakers[w]["constraints"]["total"] for w in "AB"},
            "speakers": speakers,
            "search_seconds": {w: report["characters"][w]["search_seconds"] for w in "AB"},
            "timings": report["timings"]}


def _padded(audio, seconds: float):
    """``audio`` (mono) cut or padded with silence to ``seconds``."""
    x = np.asarray(audio.samples, np.float32)
    n = int(round(seconds * audio.sample_rate))
    return type(audio)(np.concatenate([x, np.zeros(max(0, n - len(x)), np.float32)])[:n], audio.sample_rate, audio.path)


def run_from_audio(system, p: ConverseParams, params, out_dir: Path) -> dict:
    """``task=converse`` for a system that makes a whole conversation from the audio alone
    (``converses_from_audio``, e.g. ``system=flow_matching``): inputs read and annotated as for the motion
    graph (the labels are drawn on the timeline; a speaker without a transcript gets no words, nothing is
    recognized), each character's model fitted on every session of the corpus, then one call per
    speaker with its audio and the other's as the partner's. No plan, search or checker: such a system
    enforces none of the paper's constraints, and the report says so."""
    from ..evaluation.loo import fit_fold
    from ..io import save_bvh
    from ..seeding import derive_seed
    from .common import annotated_corpus, cache_dir
    from .synthesize import label_rows

    t_start = time.perf_counter()
    timings = {}
    condition = p.condition
    if condition not in system.conditions:
        if len(system.conditions) != 1:
            raise ConfigError(f"task.condition={condition!r}: system {system.name!r} has the conditions "
                              f"{sorted(system.conditions)} (set task.condition)")
        condition = next(iter(system.conditions))
        log.info("task.condition=%s is not a condition of system %s: its one condition %r is used", p.condition,
                 system.name, condition)
    fps = params.fps
    t0 = time.perf_counter()
    A, B, duration = load_inputs(p, recognize=False)
    seg = {"A": annotate(A, params), "B": annotate(B, params)}
    timings["inputs_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    _, ann = annotated_corpus(params)
    chars = characters_of(p, ann)
    timings["corpus_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    models = fit_fold(system, ann, None, condition, cache_dir(params))
    timings["models_s"] = time.perf_counter() - t0
    T = int(round(duration * fps))
    audio = {"A": _padded(A.audio, duration), "B": _padded(B.audio, duration)}
    motions, report_chars = {}, {}
    t0 = time.perf_counter()
    for k, (who, other) in enumerate(("AB", "BA")):
        t1 = time.perf_counter()
        seed = derive_seed(params.seed, fold=0, condition=condition, session="converse", window_frame=0, role_index=k)
        motions[who] = system.synthesize_audio(models[chars[k]], audio[who], audio[other], T, fps, seed,
                                               chair_index=k, name=f"{system.name}:converse:{who}")
        if motions[who].num_frames != T:
            raise SearchFailure(f"system {system.name} gave {motions[who].num_frames} frames for speaker {who}, "
                                f"the conversation has {T}")
        report_chars[who] = {"character": chars[k], "success": True, "seconds": time.perf_counter() - t1,
                             "num_frames": T}
    timings["synthesis_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    for who in "AB":
        save_bvh(motions[who], out_dir / f"{who}.bvh")
    wav = out_dir / "conversation.wav"
    write_stereo(wav, A.audio, B.audio, duration)
    timings["write_s"] = time.perf_counter() - t0
    video = None
    if p.video:
        t0 = time.perf_counter()
        video = render_conversation(motions, {"A": (), "B": ()}, None, seg, chars, fps, out_dir / "conversation.mp4",
                                    wav, p)
        timings["video_s"] = time.perf_counter() - t0
    timings["total_s"] = time.perf_counter() - t_start
    report = {"inputs": {"duration_s": duration, "num_frames": T, "fps": fps,
                         **{sp.name: {"character": chars[k], "audio": sp.audio_file, "channel": sp.channel,
                                      "transcript": sp.transcript_file, "words": sp.words_source,
                                      "num_words": int(len(sp.words))} for k, sp in enumerate((A, B))}},
              "system": system.name, "condition": condition, "characters": report_chars, "success": True,
              "constraints": f"not enforced by system {system.name} and not checked (it has no source frames to check)",
              "timings": timings, "segments": {w: label_rows(seg[w]) for w in "AB"}, "failure": None,
              "all_constraints_met": None,
              "outputs": {"bvh": ["A.bvh", "B.bvh"], "audio": wav.name, "video": None if video is None else video.name}}
    write_json_atomic(out_dir / "report.json", report)
    lines = [f"# Conversation: system {system.name}, condition {condition}", "",
             f"{duration:.2f} s of speech, {T} frames at {fps:g} fps.", "",
             "| speaker | character | audio | words | seconds |", "|---|---|---|---|---|"]
    lines += [f"| {w} | {chars[k]} | {report['inputs'][w]['audio']} | {report['inputs'][w]['words']} | "
              f"{report_chars[w]['seconds']:.1f} |" for k, w in enumerate("AB")]
    lines += ["", f"Constraints: {report['constraints']}.", ""]
    with atomic_path(out_dir / "report.md") as tmp:
        tmp.write_text("\n".join(lines))
    for w in "AB":
        log.info("speaker %s (%s): %d frames from the audio alone; constraints not enforced by %s", w,
                 report_chars[w]["character"], T, system.name)
    return {"success": True, "all_constraints_met": None, "system": system.name, "condition": condition,
            "duration_s": duration, "num_frames": T, "characters": {w: chars[k] for k, w in enumerate("AB")},
            "timings": timings}


def speaker_summary(report: dict, who: str, fps: float) -> dict:
    """One speaker's honest result: where the words came from, the constraints met / total by kind (the
    independent checker over the whole path), and what best effort dropped (per window, by kind) and
    which constraints the path misses (kind and seconds)."""
    ch = report["characters"][who]
    tot = ch["checker"]["total"]
    dropped: dict = {}
    windows = []
    for w in ch["windows"]:
        if w.get("status") == "best_effort":
            windows.append(int(w["index"]))
            for key in w.get("relaxed", []):
                dropped[str(key[0])] = dropped.get(str(key[0]), 0) + 1
    inp = report["inputs"][who]
    return {"character": ch["character"], "words": {"source": inp["words"], "count": inp["num_words"],
                                                    "transcript": inp["transcript"]},
            "constraints": {"met": int(tot["met"]), "total": int(tot["total"]),
                            "share": (tot["met"] / tot["total"]) if tot["total"] else 1.0, "by_kind": tot["by_kind"]},
            "best_effort": {"windows": windows, "dropped": int(sum(dropped.values())), "dropped_by_kind": dropped},
            "missed": [{"kind": d["kind"], "start_s": round(d["start"] / fps, 3), "end_s": round(d["end"] / fps, 3)}
                       for d in tot["missed"]]}


def speaker_line(who: str, s: dict) -> str:
    """The console's line of :func:`speaker_summary`."""
    c = s["constraints"]
    kinds = ", ".join(f"{k} {v['met']}/{v['total']}" for k, v in c["by_kind"].items() if v["total"])
    line = (f"speaker {who} ({s['character']}, {s['words']['count']} words, {s['words']['source']}): constraints met "
            f"{c['met']}/{c['total']} ({100 * c['share']:.0f}%; {kinds or 'none'})")
    be = s["best_effort"]
    if be["windows"]:
        line += (f"; best effort in window(s) {be['windows']} dropped {be['dropped']} ("
                 + ", ".join(f"{k} {n}" for k, n in be["dropped_by_kind"].items()) + ")")
    if s["missed"]:
        line += "; missed: " + ", ".join(f"{m['kind']} {m['start_s']:.2f}-{m['end_s']:.2f} s" for m in s["missed"][:6])
        line += " ..." if len(s["missed"]) > 6 else ""
    return line


def write_stereo(path: Path, a, b, duration: float, offsets_s=(0.0, 0.0)) -> Path:
    """A and B as the left and right channels of one WAV of ``duration`` seconds (B resampled to A's
    rate if they differ; a multichannel recording gives its first channel). ``offsets_s``: where each
    recording's time 0 lies on the WAV's timeline (a negative offset drops the recording's start);
    a speaker given as None is silent."""
    from ..io import save_wav

    rate = int((a if a is not None else b).sample_rate) if (a is not None or b is not None) else 16000
    n = int(round(duration * rate))

    def at_rate(x, offset):
        out = np.zeros(n)
        if x is None:
            return out
        s = np.asarray(x.samples, np.float64)
        s = s[:, 0] if s.ndim == 2 else s
        if int(x.sample_rate) != rate:
            t = np.arange(int(round(len(s) * rate / x.sample_rate))) / rate
            s = np.interp(t, np.arange(len(s)) / x.sample_rate, s)
        k = int(round(offset * rate))
        s = s[max(0, -k):]
        k = max(0, k)
        m = max(0, min(n - k, len(s)))
        out[k:k + m] = s[:m]
        return out

    return save_wav(path, np.stack([at_rate(a, offsets_s[0]), at_rate(b, offsets_s[1])], axis=1), rate)


def render_conversation(motions: dict, ticks: dict, spans, seg, chars, fps, path: Path, wav: Path,
                        p: ConverseParams) -> Path:
    """``conversation.mp4`` (:func:`convsynth_jax.render.render_video`): both characters seen in their
    chairs, a timeline of each speaker's labels with ``ticks[who]`` (seconds: the character's synthetic
    transitions) and the windows ``spans`` ((start, end) seconds; None: one window), the conversation's audio. ``task.video_dpi`` sets the
    size: 80 draws 640 x 360 pixels of bodies."""
    from ..render import Panel, Timeline, body_from_motion, render_video

    names = [f"{w} ({chars[k]})" for k, w in enumerate("AB")]
    bodies = tuple(body_from_motion(motions[w], names[k]) for k, w in enumerate("AB"))
    timelines = [Timeline(names[k], seg[w], tuple(ticks[w]), k) for k, w in enumerate("AB")]
    if spans:
        timelines.append(Timeline("windows", pd.DataFrame({"kind": [f"W{i}" for i in range(len(spans))],
                                                           "start": [a for a, _ in spans],
                                                           "end": [b for _, b in spans]})))
    scale = p.video_dpi / 80.0
    return render_video([Panel(f"{names[0]} and {names[1]}", bodies)], timelines, fps, path, audio=wav,
                        render_fps=p.video_fps, panel_width=int(round(640 * scale)), panel_height=int(round(360 * scale)))
