"""Speech timing: the measurements (data/speech_timing.py) and the default synthetic corpus against
real speech, both measured with the annotation pipeline (docs/synthetic_corpus.md)."""
import logging

import numpy as np
import pandas as pd
import pytest
from conftest import shared_path
from scipy import stats

from convsynth_jax.data import make_synthetic_corpus, resolve_config
from convsynth_jax.data.speech_timing import (PAUSE_MIN, channel_timing, compare, corpus_timing, distribution_summary,
                                              ks_distance, speech_folder_timing, turn_gaps)
from convsynth_jax.data.synthetic import config_hash
from convsynth_jax.io import load_corpus

# KS distance of clause durations, default synthetic corpus vs real speech
CLAUSE_KS = 0.1


def _seg(rows):
    return pd.DataFrame(rows, columns=["kind", "start", "peak", "end"])


def test_channel_timing_on_a_hand_made_channel():
    words = pd.DataFrame({"start": [0.0, 0.3, 0.6, 1.5, 1.8, 3.0, 4.0],
                          "end": [0.25, 0.55, 1.0, 1.75, 2.0, 3.4, 4.5],
                          "word": ["we", "went", "home", "um", "then", "it", "rained"]})
    seg = _seg([("PC", 0.0, 0.25, 1.0), ("HP", 1.5, 1.6, 1.75), ("PC", 1.8, 1.9, 2.0), ("PC", 3.0, 4.25, 4.5)])
    partner = _seg([("PC", 2.2, 2.5, 2.9)])  # the partner speaks in the gap 2.0-3.0
    t = channel_timing(words, seg, partner)
    np.testing.assert_allclose(t.clause_seconds, [1.0, 0.2, 1.5])
    np.testing.assert_allclose(t.clause_words, [3, 1, 2])
    np.testing.assert_allclose(t.peak_position, [0.25, 0.5, 1.25 / 1.5])
    np.testing.assert_allclose(t.clause_rate, [3.0, 5.0, 2 / 1.5])
    # gaps 0.05, 0.05, 0.5, 0.05, 1.0 (partner inside: no pause), 0.6; the 0.05 s gaps are no pauses
    assert PAUSE_MIN > 0.05
    np.testing.assert_allclose(t.pause_seconds, [0.5, 0.6])
    np.testing.assert_allclose(np.sort(t.word_seconds), np.sort([0.25, 0.25, 0.4, 0.2, 0.4, 0.5]))
    assert (t.words, t.fillers) == (7, 1) and t.filler_rate == pytest.approx(100 / 7)
    # a monologue: the 1.0 s gap is a pause
    np.testing.assert_allclose(channel_timing(words, seg).pause_seconds, [0.5, 1.0, 0.6])


def test_turn_gaps_are_floor_transfer_offsets():
    a = _seg([("PC", 0.0, 0.5, 1.0), ("PC", 1.2, 1.5, 2.0), ("HP", 2.1, 2.2, 2.3), ("PC", 5.0, 5.5, 6.0)])
    b = _seg([("LR", 1.9, 1.95, 2.0), ("PC", 2.5, 3.0, 4.0), ("PC", 5.8, 6.0, 7.0)])
    np.testing.assert_allclose(turn_gaps(a, b), [0.5, 1.0, -0.2])  # 2.0 -> 2.5, 4.0 -> 5.0, 6.0 -> 5.8


def test_ks_distance_and_summary_against_plain_computation():
    rng = np.random.default_rng(0)
    a, b = rng.normal(0, 1, 40), rng.normal(0.3, 1.2, 70)
    grid = np.sort(np.concatenate([a, b]))
    fa = np.array([(a <= x).mean() for x in grid])
    fb = np.array([(b <= x).mean() for x in grid])
    assert ks_distance(a, b) == pytest.approx(np.abs(fa - fb).max())
    s = distribution_summary(a)
    assert s["n"] == 40 and s["median"] == pytest.approx(np.median(a)) and s["max"] == a.max()
    assert np.isnan(ks_distance(a, []))


def test_default_timing_changes_the_cache_key():
    """The cached default corpus (data_cache/, keyed by config_hash) is regenerated with the new
    timing: the default parameters and those of the version-4 timing hash differently."""
    from convsynth_jax.config import compose

    old = resolve_config(compose(["corpus=synthetic_v4_timing"]).corpus.generator)
    new = resolve_config(compose(["corpus=synthetic"]).corpus.generator)
    assert old["word_seconds_sigma"] == 0 and old["characters"]["main-agent"]["words_mean"] == 4.29
    assert config_hash(old) != config_hash(new)
    tiny = compose(["corpus=synthetic_tiny"]).corpus.generator
    assert {k: tiny[k] for k in ("word_seconds", "clause_pause", "p_hesitation", "max_clause_words")} == \
        {k: old[k] for k in ("word_seconds", "clause_pause", "p_hesitation", "max_clause_words")}


def test_planted_clause_sizes_respect_the_limits():
    from convsynth_jax.data.synthetic import _session_start

    cfg = resolve_config({"num_sessions": 2})
    sizes = [len(s.words) for i in range(2) for s in _session_start(i, cfg)[2] if s.kind == "PC"]
    assert min(sizes) >= cfg["min_clause_words"] and max(sizes) <= cfg["max_clause_words"]
    assert len(sizes) > 50


@pytest.fixture(scope="module")
def default_speech(tmp_path_factory):
    """The default corpus's conversations and voices (planting calibration off: it changes neither),
    written as files and measured with the annotation pipeline, as experiments/bench/speech_timing.py
    does. Skips (before generating) without the real recordings to compare with."""
    shared_path("speech")
    root = make_synthetic_corpus(tmp_path_factory.mktemp("speech") / "c", {"calibrate_rates": False})
    logging.getLogger("convsynth_jax.annotate.audio").setLevel(logging.ERROR)
    return corpus_timing(load_corpus(root))


@pytest.mark.slow
@pytest.mark.shared
def test_default_corpus_clauses_last_as_long_as_real_ones(speech_dir, default_speech):
    """Clause durations of the default corpus (17 x 106 s, about 740 clauses) lie within
    KS distance 0.1 of the real recordings' (21 clauses; see docs/synthetic_corpus.md for why 0.1 is
    about the best any smooth distribution reaches against them). Words per clause follow too; the
    version-4 timing (before the calibration) was 0.35 away."""
    real = speech_folder_timing(speech_dir)
    assert real.clause_seconds.size >= 15
    cmp = compare(real, default_speech)
    assert cmp["clause_seconds"]["ks"] <= CLAUSE_KS, cmp["clause_seconds"]
    assert cmp["clause_words"]["ks"] <= 0.15, cmp["clause_words"]
    # and the match is no accident of the test statistic: medians within 0.15 s and 1 word
    assert abs(cmp["clause_seconds"]["real"]["median"] - cmp["clause_seconds"]["synthetic"]["median"]) <= 0.15
    assert abs(cmp["clause_words"]["real"]["median"] - cmp["clause_words"]["synthetic"]["median"]) <= 1.0
    # a two-sample test does not tell the corpora apart
    assert stats.ks_2samp(real.clause_seconds, default_speech.clause_seconds).pvalue > 0.5
