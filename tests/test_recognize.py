"""The offline recognizer and aligner (io/recognize.py) on 5 s of real speech (tests/data/speech_clip.*)."""
import numpy as np
import pandas as pd
import pytest

from conftest import TEST_DATA
from convsynth_jax.errors import TranscriptFormatError
from convsynth_jax.io import load_audio, load_transcript
from convsynth_jax.io.recognize import align_phrases, number_words, recognize_words


@pytest.fixture(scope="module")
def clip():
    return load_audio(TEST_DATA / "speech_clip.wav"), load_transcript(TEST_DATA / "speech_clip.tsv")


def test_recognized_words_have_the_reference_timings(clip):
    """Words recognized from the audio alone: ordered, inside the audio, and the content words the
    recognizer gets right start within 50 ms of the hand alignment."""
    audio, ref = clip
    got = recognize_words(audio.samples, audio.sample_rate)
    assert len(got) >= 8 and (got["end"] >= got["start"]).all() and got["start"].is_monotonic_increasing
    assert got["end"].max() <= audio.duration + 1e-6
    for word in ("acoustic", "talking", "nothing", "going"):
        r = ref["start"][ref["word"] == word].iat[0]
        g = got["start"][got["word"] == word]
        assert len(g) and abs(g.iat[0] - r) < 0.05, (word, r, g.tolist())
    assert recognize_words(np.zeros(16000, np.float32), 16000).empty          # silence: no words


def test_recognizer_resamples_other_rates(clip):
    from scipy.signal import resample_poly

    audio, ref = clip
    x = resample_poly(audio.samples[:int(2.2 * audio.sample_rate)], 11025, 16000).astype(np.float32)   # "this is the acoustic corpus"
    got = recognize_words(x, 11025)
    r = ref["start"][ref["word"] == "acoustic"].iat[0]
    assert abs(got["start"][got["word"] == "acoustic"].iat[0] - r) < 0.06


def test_phrases_align_to_word_timings(clip, caplog):
    """Rows of several words (subtitles, sentences) become word timings within 50 ms of the hand
    alignment; a number is spelled out for the alignment and stays one word; a word the dictionary
    lacks is aligned letter by letter with a warning; rows of one word are kept as they are."""
    audio, ref = clip
    rows = pd.DataFrame([(0.55, 1.99, "This is the acoustic corpus,"), (1.99, 4.81, ref["word"][5:].str.cat(sep=" "))],
                        columns=["start", "end", "word"])
    got = align_phrases(rows, audio.samples, audio.sample_rate, "clip.srt")
    assert [w.strip(",").lower() for w in got["word"]] == ref["word"].tolist()
    assert np.mean(np.abs(got["start"].to_numpy() - ref["start"].to_numpy()) < 0.05) >= 0.85
    assert got["start"].is_monotonic_increasing
    odd = rows.copy()
    odd.loc[1, "word"] = odd.loc[1, "word"].replace("talking pretty", "talkingz 2")
    with caplog.at_level("WARNING"):
        got2 = align_phrases(odd, audio.samples, audio.sample_rate, "clip.srt")
    assert "talkingz" in caplog.text and "letter by letter" in caplog.text
    assert got2["word"].tolist()[6:8] == ["talkingz", "2"] and len(got2) == len(ref)
    one = pd.DataFrame([(0.96, 1.39, "acoustic")], columns=["start", "end", "word"])
    assert align_phrases(one, audio.samples, audio.sample_rate).equals(one)


def test_a_row_that_cannot_be_aligned_is_an_error_naming_it(clip):
    audio, _ = clip
    rows = pd.DataFrame([(0.55, 1.39, "this is the acoustic"),
                         (4.90, 4.95, " ".join(["extraordinarily"] * 12))], columns=["start", "end", "word"])
    with pytest.raises(TranscriptFormatError, match=r"clip\.srt: row 1: 4\.90-4\.95 s, 'extraordinarily.*cannot be "
                                                    r"aligned"):
        align_phrases(rows, audio.samples, audio.sample_rate, "clip.srt")


def test_number_words():
    assert number_words(0) == ["zero"]
    assert number_words(25) == ["twenty", "five"]
    assert number_words(1985) == ["one", "thousand", "nine", "hundred", "eighty", "five"]
    assert number_words(2_000_013) == ["two", "million", "thirteen"]
