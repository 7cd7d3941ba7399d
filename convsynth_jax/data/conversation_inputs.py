"""Conversations for ``task=converse`` built from monologue recordings (audio + word transcript), as a
new user's inputs differ: one speaker with a silent partner, two speakers taking turns, or one speaker's
recordings repeated to a length.

Each builder writes into a folder and returns the four files of a conversation
(:class:`ConversationFiles`: A's and B's audio and transcript, the task's ``task.audio_a`` ...) and its
length in seconds. A silent partner's transcript is a header-only TSV (no words). Audio is mono float32
(a multichannel recording's first channel), written as 16-bit WAV.
"""
from __future__ import annotations

from pathlib import Path
from typing import NamedTuple, Sequence

import numpy as np
import pandas as pd

from ..errors import AudioFormatError
from ..io import load_audio, load_transcript, save_wav
from ..io.transcripts import save_transcript_tsv

_NO_WORDS = "start\tend\tword\n"


class ConversationFiles(NamedTuple):
    audio_a: Path
    transcript_a: Path
    audio_b: Path
    transcript_b: Path


def _mono(samples) -> np.ndarray:
    x = np.asarray(samples, np.float32)
    return x.reshape(len(x), -1)[:, 0]


def _same_rate(audios) -> int:
    rate = audios[0].sample_rate
    for a in audios[1:]:
        if a.sample_rate != rate:
            raise AudioFormatError(f"sample rate {a.sample_rate} Hz, expected {rate} Hz as the first recording's", a.path)
    return rate


def silent_partner(folder: Path, wav: Path, transcript: Path) -> tuple[ConversationFiles, float]:
    """A speaks ``wav`` (its words from ``transcript``, any format the readers take), B is silent for as long."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    a = load_audio(wav)
    save_transcript_tsv(load_transcript(transcript), folder / "a.tsv")
    save_wav(folder / "b.wav", np.zeros(int(round(a.duration * a.sample_rate)), np.float32), a.sample_rate)
    (folder / "b.tsv").write_text(_NO_WORDS)
    return ConversationFiles(Path(wav), folder / "a.tsv", folder / "b.wav", folder / "b.tsv"), a.duration


def exchange(folder: Path, a: tuple[Path, Path], b: tuple[Path, Path], gap: float = 0.6
             ) -> tuple[ConversationFiles, float]:
    """A speaks recording ``a`` = (wav, transcript), then B answers with ``b`` after ``gap`` seconds;
    each is silent while the other speaks."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    xa, xb = load_audio(a[0]), load_audio(b[0])
    rate = _same_rate([xa, xb])
    t_b = xa.duration + gap
    n = int(round((t_b + xb.duration) * rate))
    sa, sb = np.zeros(n, np.float32), np.zeros(n, np.float32)
    sa[:len(xa.samples)] = _mono(xa.samples)
    k = int(round(t_b * rate))
    mb = _mono(xb.samples)
    sb[k:k + len(mb)] = mb[:n - k]
    save_wav(folder / "a.wav", sa, rate)
    save_wav(folder / "b.wav", sb, rate)
    save_transcript_tsv(load_transcript(a[1]), folder / "a.tsv")
    wb = load_transcript(b[1])
    wb[["start", "end"]] += t_b
    save_transcript_tsv(wb, folder / "b.tsv")
    return ConversationFiles(folder / "a.wav", folder / "a.tsv", folder / "b.wav", folder / "b.tsv"), n / rate


def repeated_speech(folder: Path, recordings: Sequence[tuple[Path, Path]], seconds: float, pause: float = 0.5
                    ) -> tuple[ConversationFiles, float]:
    """A speaks the recordings (wav, transcript) one after another with ``pause`` seconds between them,
    from the first again, until ``seconds``; B is silent. Words that end after ``seconds`` are dropped."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    recs = [(load_audio(w), load_transcript(t)) for w, t in recordings]
    rate = _same_rate([a for a, _ in recs])
    gap = np.zeros(int(pause * rate), np.float32)
    parts, words, t = [], [], 0.0
    while t < seconds:
        for a, wd in recs:
            if t >= seconds:
                break
            parts += [_mono(a.samples), gap]
            w = wd.copy()
            w[["start", "end"]] += t
            words.append(w)
            t += a.duration + pause
    samples = np.concatenate(parts)[:int(round(seconds * rate))]
    words = pd.concat(words, ignore_index=True)
    save_wav(folder / "a.wav", samples, rate)
    save_transcript_tsv(words[words["end"] <= seconds].reset_index(drop=True), folder / "a.tsv")
    save_wav(folder / "b.wav", np.zeros_like(samples), rate)
    (folder / "b.tsv").write_text(_NO_WORDS)
    return ConversationFiles(folder / "a.wav", folder / "a.tsv", folder / "b.wav", folder / "b.tsv"), len(samples) / rate
