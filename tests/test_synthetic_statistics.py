"""Statistics of a written synthetic corpus (convsynth_jax.data.synthetic.statistics) on the tiny corpus:
every rate a share, counts that add up to the planted files."""
from __future__ import annotations

import json

import pandas as pd

from convsynth_jax.data.synthetic.config import ROLES
from convsynth_jax.data.synthetic.statistics import detector_counts, difficulty, realized_rates


def test_realized_rates_cover_every_character_and_hypothesis(tiny_corpus_dir):
    rows = realized_rates(tiny_corpus_dir)
    ev = pd.read_csv(tiny_corpus_dir / "events.csv")
    names = {json.loads((tiny_corpus_dir / "corpus.json").read_text())["config"]["characters"][r]["name"] for r in ROLES}
    assert {r["character"] for r in rows} == names
    for r in rows:
        for k in ("realized_detector", "realized_window", "realized_causal"):
            assert 0.0 <= r[k] <= 1.0, (r["hypothesis"], k)
        assert abs(r["detector_minus_configured_pp"] - 100 * (r["realized_detector"] - r["configured"])) < 1e-9
    # the own-channel PC rows count the character's own planted clauses
    pc = {r["character"]: r["segments"] for r in rows if r["hypothesis"] == "PC-LH"}
    cfg = json.loads((tiny_corpus_dir / "corpus.json").read_text())["config"]["characters"]
    assert pc == {cfg[r]["name"]: int(((ev.kind == "PC") & (ev.participant == r)).sum()) for r in ROLES}


def test_detector_counts_never_match_more_segments_than_there_are(tiny_corpus_dir):
    ev = pd.read_csv(tiny_corpus_dir / "events.csv")
    for (role, h), (hit, n) in detector_counts(tiny_corpus_dir, ev).items():
        assert 0 <= hit <= n, (role, h)


def test_difficulty_reads_shares_and_the_glitch_file(tiny_corpus_dir):
    d = difficulty(tiny_corpus_dir)
    for k in ("overlapping_speech_share_of_speech_time", "listener_responses_over_partner_clause",
              "clauses_starting_inside_partner_clause", "same_hand_gesture_pairs_coarticulated"):
        assert 0.0 <= d[k] <= 1.0, k
    words = d["words_per_pause_free_stretch"]["all"]
    assert 1 <= words["median"] <= words["max"] and words["count"] == sum(d["words_per_pause_free_stretch"]["histogram_1_to_20plus"])
    assert d["glitches"] == len(pd.read_csv(tiny_corpus_dir / "glitches.csv"))
