"""Conversations built from monologues (convsynth_jax.data.conversation_inputs): lengths, who is silent
when, and where the words land."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from convsynth_jax.data.conversation_inputs import exchange, repeated_speech, silent_partner
from convsynth_jax.errors import AudioFormatError
from convsynth_jax.io import load_audio, load_transcript, save_wav
from convsynth_jax.io.transcripts import save_transcript_tsv

RATE = 8000


def _recording(tmp_path, name, seconds, words, rate=RATE, channels=1):
    t = np.arange(int(seconds * rate)) / rate
    x = 0.5 * np.sin(2 * np.pi * 220 * t)
    wav = tmp_path / f"{name}.wav"
    save_wav(wav, np.stack([x] * channels, 1) if channels > 1 else x, rate)
    tsv = tmp_path / f"{name}.tsv"
    save_transcript_tsv(pd.DataFrame(words, columns=["start", "end", "word"]), tsv)
    return wav, tsv


def test_silent_partner_is_as_long_and_says_nothing(tmp_path):
    wav, tsv = _recording(tmp_path, "a", 1.5, [(0.1, 0.4, "hello"), (0.6, 1.0, "there")])
    files, dur = silent_partner(tmp_path / "conv", wav, tsv)
    assert dur == pytest.approx(1.5)
    b = load_audio(files.audio_b)
    assert b.samples.shape[0] == int(1.5 * RATE) and not np.any(b.samples)
    assert list(load_transcript(files.transcript_a)["word"]) == ["hello", "there"]
    assert files.audio_a == wav


def test_exchange_takes_turns_after_the_gap(tmp_path):
    a = _recording(tmp_path, "a", 1.0, [(0.2, 0.5, "one")])
    b = _recording(tmp_path, "b", 0.5, [(0.1, 0.3, "two")], channels=2)     # B's first channel is used
    files, dur = exchange(tmp_path / "conv", a, b, gap=0.25)
    assert dur == pytest.approx(1.75)
    xa, xb = load_audio(files.audio_a).samples, load_audio(files.audio_b).samples
    k = int(1.25 * RATE)
    assert len(xa) == len(xb) == int(1.75 * RATE)
    assert np.any(xa[:k]) and not np.any(xa[k:]) and not np.any(xb[:k]) and np.any(xb[k:])
    wb = load_transcript(files.transcript_b)
    assert (wb["start"].iloc[0], wb["end"].iloc[0]) == pytest.approx((1.35, 1.55))


def test_repeated_speech_cycles_to_the_length_and_drops_words_past_it(tmp_path):
    recs = [_recording(tmp_path, "a", 1.0, [(0.1, 0.9, "first")]), _recording(tmp_path, "b", 0.5, [(0.1, 0.4, "second")])]
    files, dur = repeated_speech(tmp_path / "conv", recs, seconds=3.5, pause=0.5)
    assert dur == pytest.approx(3.5)
    words = load_transcript(files.transcript_a)
    # a at 0, b at 1.5, a again at 2.5 (its word ends at 3.4), b again at 4.0 (past the end): dropped
    assert list(words["word"]) == ["first", "second", "first"]
    assert words["start"].tolist() == pytest.approx([0.1, 1.6, 2.6])
    assert not np.any(load_audio(files.audio_b).samples)


def test_recordings_of_different_rates_are_refused(tmp_path):
    a = _recording(tmp_path, "a", 0.5, [(0.1, 0.2, "x")])
    b = _recording(tmp_path, "b", 0.5, [(0.1, 0.2, "y")], rate=16000)
    with pytest.raises(AudioFormatError, match="16000 Hz"):
        exchange(tmp_path / "conv", a, b)
