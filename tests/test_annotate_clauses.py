"""Phonemic clauses from prosody and the F0 octave guard: fluent synthetic speech
without pauses, a planted octave jump, the dynamic program against every segmentation of short
runs, and the real speech in ../shared/data/speech."""
import itertools

import numpy as np
import pandas as pd
import pytest

from convsynth_jax.annotate.audio import annotate_audio, load_word_corpus, normalize_word, segment_words
from convsynth_jax.annotate.clauses import (WordProsody, boundary_evidence, guard_f0, segmentation_score, split_run,
                                            syllables)
from convsynth_jax.annotate.params import AnnotateParams
from convsynth_jax.data.fluent import fluent_speech
from convsynth_jax.data.synthetic import VOCAB, Segment, _render_voice
from convsynth_jax.errors import ConfigError
from convsynth_jax.io.audio import Audio

BOUNDARY_TOL = 0.15  # s: a detected clause start within this of a planted one is a hit


def boundary_hits(detected_starts, planted_starts):
    """(hits among planted, planted, hits among detected, detected) for clause boundaries (every
    clause start but the first)."""
    det, pl = np.asarray(detected_starts)[1:], np.asarray(planted_starts)[1:]
    hp = sum(bool(det.size) and np.abs(det - b).min() < BOUNDARY_TOL for b in pl)
    hd = sum(bool(pl.size) and np.abs(pl - d).min() < BOUNDARY_TOL for d in det)
    return hp, len(pl), hd, len(det)


# ------------------------------------------------------------------------- fluent speech
@pytest.mark.parametrize("seed,f0_base", [(1, 210.0), (2, 118.0)])
def test_fluent_sentence_without_pauses_is_split_at_f0_resets(seed, f0_base):
    sizes = [4, 6, 3, 5, 2, 4, 7]  # 31 words, seven clauses, not one pause
    audio, w, segs = fluent_speech(seed, sizes, f0_base)
    assert (w["start"].to_numpy()[1:] - w["end"].to_numpy()[:-1]).max() < 0.08
    seg = annotate_audio(w, audio, AnnotateParams())
    pc = seg[seg["kind"] == "PC"]
    n_words = pc["text"].str.split().str.len()
    assert n_words.sum() == 31 and n_words.max() <= 15 and 3 <= n_words.mean() <= 7
    hp, n_p, hd, n_d = boundary_hits(pc["start"], [s.start for s in segs])
    assert hp / n_p >= 0.8 and hd / n_d >= 0.8, (hp, n_p, hd, n_d, n_words.tolist())
    # the peak of a recovered clause is its stressed word's F0 peak (the planted peak)
    for s in segs:
        same = pc[(np.abs(pc["start"] - s.start) < BOUNDARY_TOL) & (np.abs(pc["end"] - s.end) < BOUNDARY_TOL)]
        if len(same):
            assert abs(float(same["peak"].iloc[0]) - s.peak) < 0.1
    # the pause method leaves the whole sentence as one clause (why the prosodic method is the default)
    old = annotate_audio(w, audio, AnnotateParams(clause_method="pause"))
    assert old["kind"].tolist() == ["PC"]


def test_prosodic_method_keeps_pause_delimited_clauses_of_the_synthetic_corpus_whole():
    """Clauses separated by pauses (as in the default synthetic corpus) are not split further."""
    rng = np.random.default_rng(5)
    t, segs, words = 0.3, [], []
    for n in (8, 3, 10, 1, 5):
        ws, w0 = [], t
        for _ in range(n):
            d = rng.uniform(0.2, 0.34)
            ws.append([t, t + d, VOCAB[rng.integers(len(VOCAB))], False])
            t += d + rng.uniform(0.03, 0.07)
        t = ws[-1][1]
        k = int(rng.integers(n))
        ws[k][3] = True
        segs.append(Segment("a", "PC", w0, t, 0.5 * (ws[k][0] + ws[k][1]), [tuple(x) for x in ws]))
        words += [tuple(x[:3]) for x in ws]
        t += rng.uniform(0.45, 0.8)
    x, _ = _render_voice(segs, 180.0, t + 0.5, 16000, rng, 0.28)
    seg = annotate_audio(pd.DataFrame(words, columns=["start", "end", "word"]), Audio(x.astype(np.float32), 16000),
                         AnnotateParams())
    assert seg["text"].str.split().str.len().tolist() == [8, 3, 10, 1, 5]


# ----------------------------------------------------------------------------- the DP
def _brute_force(ev, prom, params, max_words):
    m = prom.size
    best, arg = -np.inf, None
    for cuts in itertools.product((0, 1), repeat=m - 1):
        b = [0] + [k + 1 for k in range(m - 1) if cuts[k]] + [m]
        seg = list(zip(b[:-1], b[1:]))
        s = segmentation_score(seg, ev, prom, params, max_words)
        if s > best + 1e-12:
            best, arg = s, seg
    return best, arg


@pytest.mark.parametrize("seed", range(6))
def test_dynamic_program_finds_the_best_segmentation(seed):
    rng = np.random.default_rng(seed)
    params = AnnotateParams()
    for m in (1, 2, 5, 9, 11):
        ev = rng.normal(0, 2, m - 1)
        prom = rng.normal(0, 1, m)
        for max_words in (3, 12):
            cuts = split_run(ev, prom, None, params, max_words)
            assert [c for seg in cuts for c in range(*seg)] == list(range(m))
            assert max(j - i for i, j in cuts) <= max_words
            best, _ = _brute_force(ev, prom, params, max_words)
            assert segmentation_score(cuts, ev, prom, params, max_words) == pytest.approx(best)


def test_boundary_evidence_by_hand():
    w = pd.DataFrame({"start": [0.0, 0.4, 1.2, 1.6], "end": [0.3, 0.9, 1.5, 1.9], "word": ["the", "dog", "ran", "off"]})
    n = len(w)
    pros = WordProsody(f0_max=np.zeros(n), f0_low=np.zeros(n), f0_start=np.array([0.0, 0.0, 2.0, -1.0]),
                       f0_end=np.array([0.0, -1.0, 0.0, 0.0]), energy=np.full(n, np.nan), dur_ratio=np.ones(n),
                       prominence=np.zeros(n))
    p = AnnotateParams(max_gap=0.3)
    ev = boundary_evidence(w, np.arange(n), pros, p)
    # after "the": gap 0.1 s, reset min(0, 2) - 0 = 0, no lengthening, a proclitic
    assert ev[0] == pytest.approx(p.clause_w_pause * 0.1 / 0.3 - p.clause_w_function)
    # after "dog": gap 0.3 s (full pause), reset min(2, -1) - (-1) = 0
    assert ev[1] == pytest.approx(p.clause_w_pause)
    # after "ran": gap 0.1 s, reset -1 - 0 = -1 semitone
    assert ev[2] == pytest.approx(p.clause_w_pause / 3 - p.clause_w_reset * 1.0 / p.clause_reset_semitones)


def test_syllable_estimates():
    assert [syllables(x) for x in ("the", "acoustic", "corpus", "intensity", "make", "table", "I'm", "")] == \
        [1, 3, 2, 4, 1, 2, 1, 1]


def test_unknown_clause_method_is_a_config_error():
    w = pd.DataFrame({"start": [0.0], "end": [0.2], "word": ["a"]})
    with pytest.raises(ConfigError, match="clause_method"):
        segment_words(w, params=AnnotateParams(clause_method="syntax"))


def test_clause_method_from_the_config():
    from convsynth_jax.config import default_params

    assert default_params().annotate.clause_method == "prosodic"
    assert default_params(["annotate.clause_method=pause"]).annotate.clause_method == "pause"


# ------------------------------------------------------------------------------ octave guard
def test_guard_drops_a_planted_octave_jump_in_a_track():
    t = np.arange(0, 1.0, 0.01)
    f0 = 176.0 * (1.0 + 0.1 * np.exp(-((t - 0.5) / 0.08) ** 2))  # an accent peaking at 194 Hz
    f0[20:24] = 2 * f0[20:24]                                    # the tracker doubles 4 frames
    f0[80:83] = np.nan
    g = guard_f0(t, f0, AnnotateParams())
    assert g.dropped[20:24].all() and g.dropped.sum() == 4
    assert np.nanmax(g.f0) == pytest.approx(176.0 * 1.1, rel=0.01)
    assert abs(t[np.nanargmax(g.f0)] - 0.5) <= 0.02
    assert g.median == pytest.approx(np.nanmedian(f0), rel=0.02)


def test_guard_drops_a_sustained_stretch_outside_the_speakers_range():
    """A tracker stuck an octave and a half up for 0.4 s (longer than the running median's window,
    so only the speaker-range check can catch it) is dropped; a stretch half an octave up is kept."""
    t = np.arange(0, 2.0, 0.01)
    f0 = np.full(t.size, 150.0)
    f0[50:90] = 150.0 * 2 ** 1.5   # 425 Hz for 0.4 s: outside median +- 1 octave
    f0[130:170] = 150.0 * 2 ** 0.5  # 212 Hz: a high but plausible stretch
    g = guard_f0(t, f0, AnnotateParams())
    assert g.dropped[50:90].all()
    assert not g.dropped[130:170].any()
    assert np.nanmax(g.f0) == pytest.approx(212.1, rel=0.01)


def _voice(f, sr=16000):
    phase = 2 * np.pi * np.cumsum(f) / sr
    x = 0.3 * sum(np.sin(k * phase) / k for k in range(1, 8))
    x[f <= 0] = 0.0
    return Audio(x.astype(np.float32), sr)


def test_tracker_octave_jump_gives_a_peak_in_the_speakers_range(monkeypatch):
    """A pitch track that doubles for 50 ms inside a clause (what Praat does on creaky or weak
    voicing in real speech): the clause's peak is the real accent, and the segment is flagged."""
    import convsynth_jax.annotate.audio as audio_mod

    t = np.arange(0, 2.4, 0.01)
    f0 = 176.0 * (1.0 - 0.08 * t / 2.4) * (1.0 + 0.12 * np.exp(-((t - 1.5) / 0.1) ** 2))  # accent at 1.5 s
    f0[(t < 0.1) | (t > 2.3)] = np.nan
    f0[60:65] *= 2.0                                          # 340-350 Hz for a 176 Hz speaker
    monkeypatch.setattr(audio_mod, "f0_track", lambda audio, params: (t, f0.copy()))
    silent = Audio(np.zeros(int(2.4 * 16000), np.float32), 16000)
    w = pd.DataFrame({"start": [0.1, 0.5, 0.9, 1.35, 1.8], "end": [0.45, 0.85, 1.3, 1.75, 2.3],
                      "word": ["we", "went", "to", "london", "then"]})
    for method in ("pause", "prosodic"):
        seg = annotate_audio(w, silent, AnnotateParams(clause_method=method))
        pc = seg[seg["kind"] == "PC"]
        assert pc["f0_peak"].max() < 176.0 * 1.3                  # no peak at 340-350 Hz
        top = pc.loc[pc["f0_peak"].idxmax()]
        assert abs(top["peak"] - 1.5) < 0.05
        jump = pc[(pc["start"] <= 0.6) & (pc["end"] >= 0.65)]
        assert len(jump) == 1 and bool(jump["f0_suspect"].iloc[0])


def test_praat_octave_jump_cost_holds_a_short_doubled_stretch():
    sr = 16000
    t = np.arange(int(2.4 * sr)) / sr
    f = 176.0 * (1.0 - 0.08 * t / 2.4) * (1.0 + 0.12 * np.exp(-((t - 1.5) / 0.1) ** 2))  # true peak at 1.5 s
    f[(t > 0.6) & (t < 0.66)] *= 2.0                       # an octave jump of 60 ms
    f[(t < 0.1) | (t > 2.3)] = 0.0
    audio = _voice(f, sr)
    w = pd.DataFrame({"start": [0.1, 0.5, 0.9, 1.35, 1.8], "end": [0.45, 0.85, 1.3, 1.75, 2.3],
                      "word": ["we", "went", "to", "london", "then"]})
    seg = annotate_audio(w, audio, AnnotateParams(clause_method="pause"))
    assert seg["kind"].tolist() == ["PC"]
    assert seg.loc[0, "f0_peak"] < 176.0 * 1.3 and abs(seg.loc[0, "peak"] - 1.5) < 0.05


def test_guard_keeps_a_smooth_pitch_accent():
    sr = 16000
    t = np.arange(int(1.2 * sr)) / sr
    f = 120 + 60 * np.exp(-((t - 0.6) / 0.12) ** 2)
    f[(t < 0.1) | (t > 1.1)] = 0.0
    seg = annotate_audio(pd.DataFrame({"start": [0.15], "end": [1.05], "word": ["hello"]}), _voice(f, sr),
                         AnnotateParams())
    assert seg.loc[0, "peak"] == pytest.approx(0.6, abs=0.025) and seg.loc[0, "f0_peak"] > 170
    assert not seg.loc[0, "f0_suspect"]


# ------------------------------------------------------------------------------ real speech
FILLERS = {"uh", "um", "yknow"}


@pytest.mark.parametrize("name", ["acoustic_corpus", "cold_corpus"])
def test_real_speech_clauses_have_paper_like_sizes(speech_dir, name):
    from convsynth_jax.io import load_audio, load_transcript

    w = load_transcript(speech_dir / f"{name}.TextGrid")
    seg = annotate_audio(w, load_audio(speech_dir / f"{name}.wav"), AnnotateParams())
    n_words = seg.loc[seg["kind"] == "PC", "text"].str.split().str.len()
    assert 3 <= n_words.mean() <= 7 and n_words.max() <= 15, n_words.tolist()
    # no filler label on a content word: every HP is a filler or a lexical filler of the word corpus
    corpus = load_word_corpus()
    for text in seg.loc[seg["kind"] == "HP", "text"]:
        assert " ".join(normalize_word(x) for x in text.split()) in set(corpus["hesitation"]), text
    # and every transcribed filler is a hesitation, not part of a clause
    pcs = seg.loc[seg["kind"] == "PC", "text"].str.lower().str.split()
    assert not pcs.apply(lambda ws: bool(FILLERS & set(ws))).any()
    # guarded peaks stay within an octave of the speaker's median
    f0 = seg["f0_peak"].dropna()
    assert (f0 <= 2.0 * f0.median()).all() and (f0 >= 0.5 * f0.median()).all()


# ------------------------------------------- octave errors longer than the running median
def _real_track(speech_dir, name):
    from convsynth_jax.annotate.audio import f0_track
    from convsynth_jax.io import load_audio, load_transcript

    audio = load_audio(speech_dir / f"{name}.wav")
    times, f0 = f0_track(audio, AnnotateParams())
    return audio, load_transcript(speech_dir / f"{name}.TextGrid"), times, f0


def test_planted_sustained_octave_jump_in_real_speech_is_caught(speech_dir, monkeypatch):
    """A real voice (acoustic_corpus: median about 99 Hz, 95th percentile about 151 Hz) whose track
    doubles over the word "there's" (3.74-3.93 s, 91-100 Hz -> 182-200 Hz: near twice the median,
    above the speaker's range, too long for the running median): the clause's peak stays in the
    speaker's range and the clause is flagged. Before the speaker-range rule its peak was 198 Hz,
    on the doubled stretch, unflagged."""
    import convsynth_jax.annotate.audio as audio_mod

    audio, words, times, f0 = _real_track(speech_dir, "acoustic_corpus")
    planted = f0.copy()
    jump = (times >= 3.735) & (times <= 3.935) & np.isfinite(f0)
    assert jump.sum() >= 14 and np.nanmax(f0[jump]) <= 101.0
    planted[jump] *= 2.0
    monkeypatch.setattr(audio_mod, "f0_track", lambda a, p: (times, planted.copy()))
    seg = annotate_audio(words, audio, AnnotateParams())
    hit = seg[(seg["kind"] == "PC") & (seg["start"] <= 3.8) & (seg["end"] >= 3.8)]
    assert len(hit) == 1
    assert hit["f0_peak"].iloc[0] < 1.6 * np.nanmedian(f0)        # not the planted 182-200 Hz
    assert not (3.73 <= hit["peak"].iloc[0] <= 3.94)
    assert bool(hit["f0_suspect"].iloc[0])


def test_speaker_range_rule_catches_the_real_doubled_stretch_of_cold_corpus(speech_dir):
    """cold_corpus (median about 65 Hz, 95th percentile about 81 Hz) has a real doubled stretch: the
    tracker gives 124-129 Hz at 5.91-6.14 s between frames at 61 Hz. Its clause is flagged and its
    peak lies in the speaker's range."""
    audio, words, times, f0 = _real_track(speech_dir, "cold_corpus")
    stretch = (times >= 5.9) & (times <= 6.15) & np.isfinite(f0)
    assert np.nanmin(f0[stretch]) > 1.8 * np.nanmedian(f0)               # the data is as described
    seg = annotate_audio(words, audio, AnnotateParams())
    hit = seg[(seg["kind"] == "PC") & (seg["start"] <= 6.0) & (seg["end"] >= 6.0)]
    assert len(hit) == 1 and bool(hit["f0_suspect"].iloc[0])
    assert hit["f0_peak"].iloc[0] < np.nanpercentile(f0, 95)


def test_speaker_range_rule_drops_nothing_in_clean_real_speech(speech_dir):
    """No false alarm: on acoustic_corpus (no sustained octave error) the rule drops no frame that
    the other rules keep, so the guarded contour is the same with the rule switched off."""
    _, _, times, f0 = _real_track(speech_dir, "acoustic_corpus")
    on = guard_f0(times, f0, AnnotateParams())
    off = guard_f0(times, f0, AnnotateParams(f0_near_octave_semitones=99.0))
    np.testing.assert_array_equal(on.dropped, off.dropped)
    np.testing.assert_array_equal(np.isnan(on.f0), np.isnan(off.f0))
