"""Audio annotation: word corpus, PC/LR/HP segmentation, F0 and peaks (hand-computed cases, a
synthetic voice with a known F0 contour, and the real speech in ../shared/data/speech)."""
import numpy as np
import pandas as pd
import pytest
from tolerances import F0_RELATIVE

from convsynth_jax.annotate.audio import (add_peaks, annotate_audio, f0_contour, f0_track, load_word_corpus, normalize_word,
                                          local_peaks, segment_words, word_corpus_for)
from convsynth_jax.annotate.params import AnnotateParams
from convsynth_jax.errors import ConfigError, FormatError, TranscriptFormatError
from convsynth_jax.io.audio import Audio


def words(rows):
    return pd.DataFrame(rows, columns=["start", "end", "word"])


# ------------------------------------------------------------------------------------------ corpus
def test_shipped_word_corpus_has_the_paper_examples():
    c = load_word_corpus()
    assert {"%hesitation", "uh", "um", "er", "erm", "hmm", "huh", "umm", "well", "you know", "yknow"} <= set(c["hesitation"])
    assert {"yeah", "uh-huh", "uh huh", "mm-hmm", "mhm", "right", "i see", "wow", "okay", "ok", "yes", "absolutely",
            "ah ha", "um hum"} <= set(c["listener_response"])
    assert not set(c["hesitation"]) & set(c["listener_response"])
    assert all(w == w.lower() for w in c["hesitation"] + c["listener_response"])


def test_word_corpus_overrides(tmp_path):
    inline = load_word_corpus({"listener_response": ["Indeed"], "hesitation": ["Hmmm"]}, extra={"hesitation": ["uh"]})
    assert inline == {"listener_response": ["indeed"], "hesitation": ["hmmm", "uh"]}
    f = tmp_path / "words.yaml"
    f.write_text("listener_response: [sure thing]\nhesitation: [erm]\n")
    assert load_word_corpus(f)["listener_response"] == ["sure thing"]
    f.write_text("listener_response: [ok]\nhesitation: [ok]\n")
    with pytest.raises(ConfigError, match="both lists"):
        load_word_corpus(f)
    f.write_text("listener_respons: [ok]\n")
    with pytest.raises(FormatError, match="unknown keys") as e:
        load_word_corpus(f)
    assert str(f) in str(e.value)
    f.write_text("listener_response: [ok\n")
    with pytest.raises(FormatError, match="invalid YAML"):
        load_word_corpus(f)
    with pytest.raises(FormatError, match="not found"):
        load_word_corpus(tmp_path / "missing.yaml")


def test_word_corpus_from_hydra_config():
    from convsynth_jax.config import default_params

    assert word_corpus_for(default_params().annotate) == load_word_corpus()
    p = default_params(["annotate.word_corpus={listener_response: [gotcha], hesitation: [hmm]}",
                   "annotate.extra_words.hesitation=[so]"])
    c = word_corpus_for(p.annotate)
    assert c == {"listener_response": ["gotcha"], "hesitation": ["hmm", "so"]}
    seg = annotate_audio(words([(0, 0.3, "Gotcha"), (0.4, 0.6, "so"), (0.7, 0.9, "yeah")]), None, p.annotate)
    assert seg["kind"].tolist() == ["LR", "HP", "PC"]  # "yeah" is no longer a listener response here


# ------------------------------------------------------------------------------------ segmentation
@pytest.mark.parametrize("method", ["prosodic", "pause"])
def test_segment_words_groups_clauses_and_labels_tokens(method):
    w = words([(0.0, 0.2, "So"), (0.25, 0.5, "we"), (0.55, 0.9, "went,"),     # clause 1 (punctuation ignored)
               (1.5, 1.8, "home"),                                           # pause 0.6 > 0.3: clause 2
               (1.85, 2.1, "uh"),                                            # HP splits
               (2.15, 2.4, "and"), (2.45, 2.6, "you"), (2.6, 2.8, "know"),   # "you know" is one HP
               (3.0, 3.3, "I"), (3.3, 3.5, "see"),                           # "I see" is one LR
               (3.6, 3.8, "uh"), (3.8, 4.0, "huh")])                         # "uh huh": LR, not two HPs
    seg = segment_words(w, load_word_corpus(), max_gap=0.3, params=AnnotateParams(clause_method=method))
    assert seg["kind"].tolist() == ["PC", "PC", "HP", "PC", "HP", "LR", "LR"]
    assert seg["text"].tolist() == ["So we went,", "home", "uh", "and", "you know", "I see", "uh huh"]
    assert seg[["start", "end"]].to_numpy().tolist() == [[0.0, 0.9], [1.5, 1.8], [1.85, 2.1], [2.15, 2.4],
                                                         [2.45, 2.8], [3.0, 3.5], [3.6, 4.0]]


def test_ibm_hesitation_and_hyphenated_tokens():
    seg = segment_words(words([(0, 0.3, "so"), (0.35, 0.8, "%HESITATION"), (0.9, 1.0, "uh-huh"), (1.1, 1.3, "OK")]),
                        load_word_corpus())
    assert seg["kind"].tolist() == ["PC", "HP", "LR", "LR"]


def test_max_gap_and_clause_length_limits():
    w = words([(0.0, 0.2, "a"), (0.3, 0.5, "b"), (0.6, 0.8, "c"), (0.9, 1.1, "d"), (1.2, 1.4, "e")])
    assert segment_words(w, max_gap=0.3)["text"].tolist() == ["a b c d e"]
    assert segment_words(w, max_gap=0.05)["text"].tolist() == ["a", "b", "c", "d", "e"]
    pause = AnnotateParams(clause_method="pause")  # the greedy limits of the pause method
    assert segment_words(w, max_clause_words=2, params=pause)["text"].tolist() == ["a b", "c d", "e"]
    # "c" would stretch the clause to 0.8 s > 0.7 s
    assert segment_words(w, max_clause_seconds=0.7, params=pause)["text"].tolist() == ["a b", "c d", "e"]
    # the prosodic method honours the same limits (where it cuts is its own choice)
    for kw in ({"max_clause_words": 2}, {"max_clause_seconds": 0.7}):
        seg = segment_words(w, **kw)
        assert " ".join(seg["text"]) == "a b c d e"
        assert (seg["text"].str.split().str.len() <= 2).all() and (seg["end"] - seg["start"] <= 0.7 + 1e-9).all()
    # unsorted input is put in time order first
    assert segment_words(w.iloc[::-1], max_gap=0.3)["text"].tolist() == ["a b c d e"]


def test_empty_and_bad_word_tables():
    empty = segment_words(words([]))
    assert empty.empty and list(empty.columns) == ["kind", "start", "end", "text"]
    bad = words([(0.0, 0.2, "a"), (0.5, 0.4, "b")])
    bad.attrs["path"] = "/data/s1.tsv"
    with pytest.raises(TranscriptFormatError, match=r"s1.tsv: word 1 \('b'\)"):
        segment_words(bad)
    with pytest.raises(TranscriptFormatError, match="lacks columns"):
        segment_words(pd.DataFrame({"start": [0.0], "word": ["a"]}))


# ------------------------------------------------------------------------------------------ F0 peaks
def test_add_peaks_and_local_peaks_by_hand():
    t = np.arange(0, 2, 0.01)
    f0 = np.full_like(t, 100.0)
    f0[30], f0[40], f0[41] = 150.0, 130.0, 130.0  # two local maxima in [0, 0.5]; a plateau counts once
    f0[(t > 0.95) & (t < 1.6)] = np.nan           # second segment unvoiced throughout
    seg = pd.DataFrame({"kind": ["PC", "PC"], "start": [0.0, 1.0], "end": [0.5, 1.5], "text": ["a", "b"]})
    out = add_peaks(seg, t, f0)
    assert out.loc[0, "peak"] == pytest.approx(0.30) and out.loc[0, "f0_peak"] == 150.0
    assert out.loc[1, "peak"] == pytest.approx(1.25) and np.isnan(out.loc[1, "f0_peak"])  # midpoint
    assert list(out.columns) == ["kind", "start", "peak", "end", "text", "f0_peak", "f0_suspect"]
    assert not out["f0_suspect"].any()  # no guard information given
    np.testing.assert_allclose(local_peaks(t, f0, 0.0, 0.5), [0.30, 0.40])
    assert local_peaks(t, f0, 1.0, 1.5).size == 0


def _glide_voice(sr=16000, seconds=1.2, peak_t=0.6):
    """A harmonic voice whose F0 rises from 120 Hz to 180 Hz at ``peak_t`` and falls back."""
    t = np.arange(int(seconds * sr)) / sr
    f = 120 + 60 * np.exp(-((t - peak_t) / 0.12) ** 2)
    phase = 2 * np.pi * np.cumsum(f) / sr
    x = 0.3 * sum(np.sin(k * phase) / k for k in (1, 2, 3))
    x[(t < 0.1) | (t > seconds - 0.1)] = 0.0
    return Audio(x.astype(np.float32), sr), lambda tt: 120 + 60 * np.exp(-((tt - peak_t) / 0.12) ** 2)


@pytest.mark.parametrize("backend", ["praat", "praat-fixed", "opensmile"])
def test_f0_backends_track_a_known_contour(backend):
    if backend == "opensmile":
        pytest.importorskip("opensmile")
    audio, truth = _glide_voice()
    opts = {"f0_backend": "opensmile"} if backend == "opensmile" else {"f0_range": "fixed" if "fixed" in backend else "auto"}
    t, f0 = f0_track(audio, AnnotateParams(**opts))
    v = np.isfinite(f0)
    assert v.sum() >= 80  # about 1 s voiced at a 10 ms step
    rel = np.abs(f0[v] / truth(t[v]) - 1)
    assert np.median(rel) < F0_RELATIVE / 5 and rel.max() < (2 if backend == "opensmile" else 1) * F0_RELATIVE
    seg = add_peaks(pd.DataFrame({"kind": ["PC"], "start": [0.2], "end": [1.0], "text": ["x"]}), t, f0)
    assert seg.loc[0, "peak"] == pytest.approx(0.6, abs=0.025)
    with pytest.raises(ConfigError):
        f0_track(audio, AnnotateParams(f0_backend="crepe"))


def test_f0_silence_is_unvoiced():
    t, f0 = f0_contour(Audio(np.zeros(8000, np.float32), 16000))
    assert t.size > 0 and np.isnan(f0).all()


def test_annotate_audio_without_audio_uses_midpoints():
    seg = annotate_audio(words([(0.0, 0.4, "hello"), (0.5, 0.7, "um")]), None, AnnotateParams())
    assert seg["peak"].tolist() == pytest.approx([0.2, 0.6])


# ------------------------------------------------------------------------------------- real speech
@pytest.mark.parametrize("name", ["acoustic_corpus", "cold_corpus"])
def test_real_speech_segmentation(speech_dir, name):
    from convsynth_jax.io import load_audio, load_transcript

    w = load_transcript(speech_dir / f"{name}.TextGrid")
    audio = load_audio(speech_dir / f"{name}.wav")
    seg = annotate_audio(w, audio, AnnotateParams())
    assert set(seg["kind"]) <= {"PC", "LR", "HP"} and (seg["kind"] == "PC").sum() >= 3
    fillers = w[w["word"].str.lower().isin(["uh", "um", "yknow"])]
    assert len(fillers) > 0
    hp = seg[seg["kind"] == "HP"]
    for f in fillers.itertuples():  # every filler is (inside) a hesitation pause
        assert ((hp["start"] <= f.start + 1e-9) & (hp["end"] >= f.end - 1e-9)).any(), f
    pcs = seg[seg["kind"] == "PC"]
    assert not pcs["text"].str.lower().str.split().apply(lambda ws: bool({"uh", "um", "yknow"} & set(ws))).any()
    assert ((seg["peak"] >= seg["start"]) & (seg["peak"] <= seg["end"])).all()
    voiced = seg["f0_peak"].dropna()
    assert len(voiced) >= 0.7 * len(seg) and voiced.between(60, 450).all()
    t, f0 = f0_contour(audio)
    assert 70 < np.nanmedian(f0) < 300  # a plausible adult speaking F0
    for r in pcs.itertuples():
        lp = local_peaks(t, f0, r.start, r.end)
        assert ((lp >= r.start) & (lp <= r.end)).all()


def test_unquoted_yaml_boolean_is_rejected(tmp_path):
    f = tmp_path / "words.yaml"
    f.write_text("listener_response: [yes]\nhesitation: [uh]\n")  # YAML 1.1 reads yes as True
    with pytest.raises(FormatError, match="quote"):
        load_word_corpus(f)


# ---------------------------------------------------------------------------- words in context
def _kinds(rows, **kw):
    seg = segment_words(words(rows), load_word_corpus(), params=AnnotateParams(**kw))
    out = list(zip(seg["kind"], seg["text"]))
    # these short runs are single clauses for both clause methods
    pause = segment_words(words(rows), load_word_corpus(), params=AnnotateParams(**{**kw, "clause_method": "pause"}))
    assert list(zip(pause["kind"], pause["text"])) == out
    return out


def test_like_as_a_verb_is_no_hesitation():
    rows = [(0.0, 0.2, "I"), (0.2, 0.45, "like"), (0.45, 0.6, "to"), (0.6, 0.9, "walk")]
    assert _kinds(rows) == [("PC", "I like to walk")]
    # "I like." before a pause is still the verb; "do you know" is a question, not a filler
    assert _kinds([(0.0, 0.2, "I"), (0.2, 0.5, "like")]) == [("PC", "I like")]
    assert _kinds([(0.0, 0.2, "do"), (0.2, 0.4, "you"), (0.4, 0.6, "know"), (0.6, 0.9, "him")]) == \
        [("PC", "do you know him")]
    # "stuff like that": no pause after it
    assert _kinds([(0.0, 0.3, "stuff"), (0.3, 0.5, "like"), (0.5, 0.8, "that")]) == [("PC", "stuff like that")]
    # the old word-by-word rule, still available
    assert ("HP", "like") in _kinds(rows, word_context=False)


def test_like_and_well_followed_by_a_pause_are_hesitations():
    rows = [(0.0, 0.2, "it"), (0.2, 0.4, "was"), (0.45, 0.7, "like"), (1.0, 1.4, "huge")]
    assert _kinds(rows) == [("PC", "it was"), ("HP", "like"), ("PC", "huge")]
    assert _kinds([(0.0, 0.3, "well"), (0.6, 0.8, "we"), (0.8, 1.0, "left")]) == [("HP", "well"), ("PC", "we left")]
    # pure fillers are hesitations anywhere
    assert _kinds([(0.0, 0.2, "so"), (0.2, 0.4, "um"), (0.4, 0.6, "we")]) == [("PC", "so"), ("HP", "um"), ("PC", "we")]


def test_response_word_inside_ones_clause_is_no_listener_response():
    rows = [(0.0, 0.2, "if"), (0.2, 0.3, "I"), (0.3, 0.6, "feel"), (0.65, 1.0, "okay")]
    assert _kinds(rows) == [("PC", "if I feel okay")]
    assert _kinds([(0.0, 0.3, "that's"), (0.3, 0.6, "right"), (0.6, 0.9, "there")]) == [("PC", "that's right there")]
    # a short turn of response words, or one after a pause, is a listener response
    assert _kinds([(0.0, 0.3, "okay")]) == [("LR", "okay")]
    assert _kinds([(0.0, 0.3, "we"), (0.3, 0.6, "left"), (1.2, 1.4, "oh"), (1.4, 1.7, "yeah")]) == \
        [("PC", "we left"), ("LR", "oh"), ("LR", "yeah")]
    assert ("LR", "okay") in _kinds(rows, word_context=False)


@pytest.mark.parametrize("name", ["acoustic_corpus", "cold_corpus"])
def test_real_speech_no_filler_or_response_label_on_a_content_word(speech_dir, name):
    from convsynth_jax.io import load_transcript

    corpus = load_word_corpus()
    lists = {"HP": set(corpus["hesitation"]), "LR": set(corpus["listener_response"])}
    seg = segment_words(load_transcript(speech_dir / f"{name}.TextGrid"), corpus, params=AnnotateParams())
    assert (seg["kind"] == "HP").sum() >= 3
    for kind, text in zip(seg["kind"], seg["text"]):
        if kind in lists:
            assert " ".join(normalize_word(w) for w in text.split()) in lists[kind], (kind, text)
