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
    # segments without word timestamps are phrases (aligned to the audio by the caller)
    (tmp_path / "nowords.json").write_text(json.dumps({"segments": [{"start": 0, "end": 1, "text": " hi  there"}]}))
    assert load_transcript(tmp_path / "nowords.json")["word"].tolist() == ["hi there"]
    (tmp_path / "badseg.json").write_text(json.dumps({"segments": [{"start": 0, "text": "hi"}]}))
    with pytest.raises(TranscriptFormatError, match=r"badseg\.json: segments\[0\].*'start', 'end' and 'text'"):
        load_transcript(tmp_path / "badseg.json")
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


def test_textgrid_label_over_two_lines_reads_as_praat_reads_it(tmp_path):
    """A quoted label holding a line break (Praat writes it so) is one label; the intervals after it
    keep their times; Praat reads the same file the same way."""
    import parselmouth

    df = pd.DataFrame({"start": [0.5, 2.0, 7.54], "end": [1.5, 7.54, 9.0],
                       "word": ["first one", "a sentence\nbroken over lines", "last"]})
    path = save_textgrid(df, tmp_path / "multi.TextGrid", duration=10.0)
    assert 'text = "a sentence\nbroken over lines"' in path.read_text()     # the label runs over two lines
    got = load_transcript(path)
    assert got["word"].tolist() == df["word"].tolist()
    np.testing.assert_allclose(got[["start", "end"]], df[["start", "end"]])
    tg = parselmouth.read(str(path))
    assert parselmouth.praat.call(tg, "Get label of interval", 1, 4) == "a sentence\nbroken over lines"
    # a later error still names its own line (counted across the label's line break)
    bad = tmp_path / "bad.TextGrid"
    lines = path.read_text().splitlines()
    k = next(i for i, line in enumerate(lines) if "xmin = 7.54" in line)
    lines[k] = "            xmin = \"abc\""
    bad.write_text("\n".join(lines) + "\n")
    with pytest.raises(TranscriptFormatError, match=rf"bad\.TextGrid: line {k + 1}: expected a number"):
        load_transcript(bad)


def test_binary_textgrid_is_read_by_praat(tmp_path, speech_dir):
    import parselmouth

    tg = parselmouth.read(str(speech_dir / "cold_corpus.TextGrid"))
    tg.save_as_binary_file(str(tmp_path / "bin.TextGrid"))
    got = load_transcript(tmp_path / "bin.TextGrid")
    ref = load_transcript(speech_dir / "cold_corpus.TextGrid")
    assert got["word"].tolist() == ref["word"].tolist()
    np.testing.assert_allclose(got[["start", "end"]], ref[["start", "end"]])
    with pytest.raises(TranscriptFormatError, match=r"bin\.TextGrid: no tier named 'sentences'.*'words', 'phones'"):
        load_transcript(tmp_path / "bin.TextGrid", tier="sentences")
    (tmp_path / "junk.TextGrid").write_bytes(b"\x00\x01junk")
    with pytest.raises(TranscriptFormatError, match=r"junk\.TextGrid: .*Praat"):
        load_transcript(tmp_path / "junk.TextGrid")


def test_subtitles_and_headed_tables(tmp_path):
    """SubRip and WebVTT cues (markup removed, lines joined) and TSV/CSV with a header naming the
    columns are read as phrase rows; unreadable subtitles name the file."""
    from convsynth_jax.io.transcripts import phrase_rows

    (tmp_path / "a.srt").write_text("1\n00:00:01,000 --> 00:00:03,500\n<i>Hello there,</i>\nmy friend\n\n"
                                    "2\n00:00:04,000 --> 00:00:04,600\nyes\n\n")
    srt = load_transcript(tmp_path / "a.srt")
    assert srt["word"].tolist() == ["Hello there, my friend", "yes"] and phrase_rows(srt) == [0]
    np.testing.assert_allclose(srt[["start", "end"]], [[1.0, 3.5], [4.0, 4.6]])
    (tmp_path / "a.vtt").write_text("WEBVTT\n\n00:00:01.000 --> 00:00:03.500\n<v Ann>Hello there,</v>\nmy friend\n\n"
                                    "00:04.000 --> 00:04.600\nyes\n")
    vtt = load_transcript(tmp_path / "a.vtt")
    assert vtt["word"].tolist() == srt["word"].tolist()
    np.testing.assert_allclose(vtt[["start", "end"]], srt[["start", "end"]])
    (tmp_path / "t.tsv").write_text("start\tend\ttext\n1.0\t3.5\tHello there\n4.0\t4.6\tyes\n")
    assert load_transcript(tmp_path / "t.tsv")["word"].tolist() == ["Hello there", "yes"]
    (tmp_path / "t.csv").write_text('speaker,Begin,End,Word\nann,1.0,1.4,"well, yes"\nann,1.5,1.9,no\n')
    tc = load_transcript(tmp_path / "t.csv")
    assert tc["word"].tolist() == ["well, yes", "no"] and tc["start"].tolist() == [1.0, 1.5]
    (tmp_path / "h.csv").write_text("from,until,word\n1,2,a\n")
    with pytest.raises(TranscriptFormatError, match=r"h\.csv: line 1: the header names no end column"):
        load_transcript(tmp_path / "h.csv")
    (tmp_path / "bad.srt").write_text("this is not\na subtitle file\n")
    with pytest.raises(TranscriptFormatError, match=r"bad\.srt: line 1: not valid SubRip"):
        load_transcript(tmp_path / "bad.srt")
    (tmp_path / "bad.vtt").write_text("no header here\n")
    with pytest.raises(TranscriptFormatError, match=r"bad\.vtt: not valid WebVTT"):
        load_transcript(tmp_path / "bad.vtt")
