import numpy as np
import pandas as pd
import pytest

from conftest import TEST_DATA
from convsynth_jax.errors import MissingFileError, TranscriptFormatError
from convsynth_jax.io import load_transcript, save_transcript_tsv
from convsynth_jax.io.transcripts import save_textgrid, textgrid_text


def test_long_textgrid_chooses_tier_and_unquotes():
    df = load_transcript(TEST_DATA / "words_long.TextGrid")
    assert list(df.columns) == ["start", "end", "word"]
    assert df["word"].tolist() == ["well", 'I said "hi"', "there"]
    np.testing.assert_allclose(df["start"], [0.5, 0.9, 1.4])
    with pytest.raises(TranscriptFormatError, match=r"no tier named 'phones'.*\['marks', 'words'\]"):
        load_transcript(TEST_DATA / "words_long.TextGrid", tier="phones")


def test_tsv_csv_and_ibm_json():
    tsv = load_transcript(TEST_DATA / "words.tsv")
    assert tsv["word"].tolist() == ["hello", "there", "yeah"]
    csv = load_transcript(TEST_DATA / "words.csv")
    assert csv["word"].tolist() == ["hello", "there"]
    ibm = load_transcript(TEST_DATA / "words_ibm.json")
    assert ibm["word"].tolist() == ["so", "%HESITATION", "we", "went", "yeah"]
    np.testing.assert_allclose(ibm["end"], [0.3, 0.8, 1.0, 1.3, 2.3])


def test_shared_short_format_textgrids_parse_and_match_praat(speech_dir, tmp_path):
    import parselmouth

    for name in ("acoustic_corpus", "cold_corpus"):
        df = load_transcript(speech_dir / f"{name}.TextGrid")
        assert len(df) > 50 and (df["end"] >= df["start"]).all()
        # Praat itself writes the long format; both must give the same words
        parselmouth.read(str(speech_dir / f"{name}.TextGrid")).save(str(tmp_path / "long.TextGrid"))
        long = load_transcript(tmp_path / "long.TextGrid")
        assert long["word"].tolist() == df["word"].tolist()
        np.testing.assert_allclose(long[["start", "end"]], df[["start", "end"]])


def test_round_trip_tsv(tmp_path):
    df = load_transcript(TEST_DATA / "words.tsv")
    assert load_transcript(save_transcript_tsv(df, tmp_path / "w.tsv")).equals(df)


@pytest.mark.parametrize("text,match", [
    ("0.5\t0.4\tbad\n", "negative duration"),
    ("0.1\t0.4\ta\n0.05\t0.2\tb\n", "word 1 .*out of order"),
    ("0.1\tx\ta\n", "non-numeric"),
    ("0.1\tnan\ta\n", "non-finite"),
    ("0.1 0.2\n", "expected start"),
])
def test_bad_tsv(tmp_path, text, match):
    p = tmp_path / "bad.tsv"
    p.write_text(text)
    with pytest.raises(TranscriptFormatError, match=match) as e:
        load_transcript(p)
    assert "bad.tsv" in str(e.value)


def test_bad_json_and_missing(tmp_path):
    p = tmp_path / "bad.json"
    p.write_text('{"results": [')
    with pytest.raises(TranscriptFormatError, match="bad.json: line 1"):
        load_transcript(p)
    with pytest.raises(MissingFileError):
        load_transcript(tmp_path / "none.tsv")


def test_whisper_and_whisperx_json(tmp_path, caplog):
    """Word timings as Whisper (word_timestamps=True) and WhisperX write them; a word WhisperX could not
    align (no times) is dropped with a warning naming it; an unknown JSON names both accepted kinds."""
    import json

    whisper = {"text": " So, yeah.", "segments": [
        {"id": 0, "start": 0.0, "end": 1.2, "text": " So, yeah.",
         "words": [{"word": " So,", "start": 0.1, "end": 0.4, "probability": 0.9},
                   {"word": " yeah.", "start": 0.6, "end": 1.0, "probability": 0.8}]}]}
    (tmp_path / "w.json").write_text(json.dumps(whisper))
    df = load_transcript(tmp_path / "w.json")
    assert df["word"].tolist() == ["So,", "yeah."]
    np.testing.assert_allclose(df[["start", "end"]], [[0.1, 0.4], [0.6, 1.0]])
    whisperx = {"segments": [{"start": 0.1, "end": 2.0, "text": "I have 2 cats",
                              "words": [{"word": "I", "start": 0.1, "end": 0.2, "score": 0.9},
                                        {"word": "have", "start": 0.25, "end": 0.5, "score": 0.9},
                                        {"word": "2"},
                                        {"word": "cats", "start": 1.1, "end": 1.5, "score": 0.8}]}],
                "word_segments": [{"word": "I", "start": 0.1, "end": 0.2}, {"word": "have", "start": 0.25, "end": 0.5},
                                  {"word": "2"}, {"word": "cats", "start": 1.1, "end": 1.5}]}
    (tmp_path / "x.json").write_text(json.dumps(whisperx))
    with caplog.at_level("WARNING"):
        dx = load_transcript(tmp_path / "x.json")
    assert dx["word"].tolist() == ["I", "have", "cats"]
    assert "1 word(s) without start/end" in caplog.text and "'2' (word_segments[2])" in caplog.text
    (tmp_path / "nowords.json").write_text(json.dumps({"segments": [{"start": 0, "end": 1, "text": "hi"}]}))
    with pytest.raises(TranscriptFormatError, match=r"nowords\.json: segments\[0\].*word timestamps"):
        load_transcript(tmp_path / "nowords.json")
    (tmp_path / "other.json").write_text(json.dumps({"words": []}))
    with pytest.raises(TranscriptFormatError, match=r"other\.json: expected IBM Watson.*Whisper"):
        load_transcript(tmp_path / "other.json")


def test_textgrid_writer_round_trips_through_our_reader_and_praat(tmp_path):
    df = pd.DataFrame({"start": [0.5, 0.9, 1.6], "end": [0.9, 1.4, 2.0], "word": ["well", 'I said "hi"', "there"]})
    path = save_textgrid(df, tmp_path / "w.TextGrid", duration=2.5)
    assert load_transcript(path).equals(df)
    text = textgrid_text(df, 2.5)
    assert "xmin = 0\n" in text and "xmax = 2.5\n" in text and 'text = "I said ""hi"""' in text
    assert text.count('text = ""\n') == 1 + 1 + 1                    # before the first word, between, after
    assert textgrid_text(df.iloc[:0]).count("intervals [") == 0      # no words: an empty tier
    parselmouth = pytest.importorskip("parselmouth")
    tg = parselmouth.read(str(path))                                  # Praat reads it: tiles the tier
    assert parselmouth.praat.call(tg, "Get number of intervals", 1) == len(df) + 3
