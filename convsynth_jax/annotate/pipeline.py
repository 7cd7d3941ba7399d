"""Corpus-level annotation: audio segments of both channels, motion events, per-frame audio status."""
from __future__ import annotations

import functools
import logging
from dataclasses import dataclass

import pandas as pd
from tqdm.auto import tqdm

from ..utils import show_progress_bar

from ..parallel import ordered_map
from ..skeleton import Motion
from .audio import annotate_audio, word_corpus_for
from .motion import joint_speeds, segment_motion
from .params import AnnotateParams
from .types import FrameAudio

log = logging.getLogger(__name__)


@dataclass
class ParticipantAnnotation:
    """Everything the later stages need about one participant of one session.

    segments / partner_segments: DataFrame[kind, start, peak, end, text] (seconds);
    events: detected motion events DataFrame[kind, start, peak, end, channel, segment];
    own / partner: FrameAudio at the motion frame rate; motion: the Motion at that rate.
    """

    session: str
    role: str
    character: str
    motion: Motion
    segments: pd.DataFrame
    partner_segments: pd.DataFrame
    events: pd.DataFrame
    own: FrameAudio
    partner: FrameAudio
    audio_path: str | None = None      # the participant's WAV (systems that need samples load it)
    audio_channel: int | None = None


def annotate_session(session, params: AnnotateParams, fps: float, word_corpus: dict | None = None) -> dict:
    """role -> ParticipantAnnotation for both participants of ``session`` (an object with ``name`` and
    two ``participants`` having role, character, load_motion(fps), load_audio(), load_transcript() and
    audio_path, as ``convsynth_jax.io.corpus.Session``). Motion is loaded at ``fps``;
    a participant without audio gets F0 peaks at segment midpoints."""
    corpus = word_corpus or word_corpus_for(params)
    segs = []
    for p in session.participants:
        audio = p.load_audio() if getattr(p, "audio_path", None) is not None else None
        segs.append(annotate_audio(p.load_transcript(), audio, params, word_corpus=corpus))
    out = {}
    for k, p in enumerate(session.participants):
        motion = p.load_motion(fps)
        own, partner = segs[k], segs[1 - k]
        events = segment_motion(joint_speeds(motion, params), own, motion.fps, partner, params)
        out[p.role] = ParticipantAnnotation(
            session.name, p.role, p.character, motion, own, partner, events,
            FrameAudio.from_segments(own, motion.num_frames, motion.fps),
            FrameAudio.from_segments(partner, motion.num_frames, motion.fps),
            str(p.audio_path) if getattr(p, "audio_path", None) is not None else None,
            getattr(p, "audio_channel", None))
    return out


def annotate_corpus(corpus, params: AnnotateParams, fps: float, progress: bool = True,
                    workers: int | None = None) -> dict:
    """session name -> role -> ParticipantAnnotation, for every session of ``corpus`` (e.g.
    ``convsynth_jax.io.load_corpus(...)``), with a progress bar unless ``progress`` is false; sessions
    are annotated by ``workers`` processes (``convsynth_jax.parallel``; the result does not depend on
    how many)."""
    words = word_corpus_for(params)
    sessions = list(corpus.sessions)
    with tqdm(total=len(sessions), desc="annotating sessions", disable=not show_progress_bar(progress)) as bar:
        done = ordered_map(functools.partial(annotate_session, params=params, fps=fps, word_corpus=words),
                           sessions, workers, on_done=bar.update)
    return {s.name: a for s, a in zip(sessions, done)}
