"""Scores of the annotation pipeline against a planted truth (convsynth_jax.evaluation.annotation):
each score moves when the detection is wrong and stays when it is within its tolerance."""
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from convsynth_jax.evaluation.annotation import audio_scores, detection_scores, near, overlap_counts


def seg(rows, cols=("kind", "start", "end")):
    return pd.DataFrame(rows, columns=list(cols))


def test_overlap_counts_and_near():
    planted, detected = seg([("LH", 0, 1), ("LH", 2, 3)]), seg([("LH", 0.5, 0.7), ("LH", 5, 6)])
    assert overlap_counts(planted, detected) == (1, 2, 1, 2)
    assert overlap_counts(planted, detected.iloc[:0]) == (0, 2, 0, 0)
    np.testing.assert_array_equal(near([1.0, 2.0, 3.0], [1.1, 2.3], 0.15), [True, False, False])
    assert not near([1.0], [], 0.15).any()


def _planted(shift=0.0):
    ev = pd.DataFrame([
        ("s", "a", "PC", 1.0, 2.5, "one two three", ""), ("s", "a", "PC", 4.0, 5.0, "four five", ""),
        ("s", "a", "LR", 7.0, 7.5, "yeah", ""), ("s", "a", "HP", 8.0, 8.6, "um", ""),
        ("s", "a", "LH", 1.2, 1.8, "", "PC"), ("s", "a", "Nod", 7.1, 7.4, "", "LR"),
        ("s", "a", "RH", 9.0, 9.5, "", "spontaneous")],
        columns=["session", "participant", "kind", "start", "end", "text", "source"])
    det = ev[ev.kind.isin(["PC", "LR", "HP"])][["kind", "start", "end", "text"]].copy()
    det.loc[det.kind == "PC", ["start", "end"]] += shift
    return ev, det.reset_index(drop=True)


@pytest.mark.parametrize("shift, found", [(0.0, 1.0), (0.1, 1.0), (0.2, 0.0)])
def test_clause_boundaries_match_within_the_tolerance(shift, found):
    ev, det = _planted(shift)
    ann = {"s": {"a": SimpleNamespace(segments=det)}}
    out = audio_scores(ann, ev)
    assert out["PC"]["recall"] == found and out["PC"]["precision"] == found
    assert out["LR"] == {"recall": 1.0, "precision": 1.0, "planted": 1, "detected": 1}
    assert out["words_per_clause"]["detected"]["histogram"] == {2: 1, 3: 1}
    ann["s"]["a"] = SimpleNamespace(segments=det[det.kind != "HP"])      # a missed hesitation
    assert audio_scores(ann, ev)["HP"]["recall"] == 0.0


def test_motion_recall_counts_caused_movements_precision_every_planted_one():
    ev, _ = _planted()
    right = seg([("LH", 1.3, 1.6), ("Nod", 7.2, 7.3), ("RH", 9.1, 9.2)])
    s = detection_scores({"s": {"a": SimpleNamespace(events=right)}}, ev)
    assert (s["recall"], s["precision"], s["planted_caused"], s["detected"]) == (1.0, 1.0, 2, 3)
    wrong = seg([("LH", 3.0, 3.5), ("Nod", 7.2, 7.3)])      # the hand event where nothing was planted
    s = detection_scores({"s": {"a": SimpleNamespace(events=wrong)}}, ev)
    assert s["recall"] == 0.5 and s["precision"] == 0.5 and s["per_kind"]["LH"] == {"recall": 0.0, "precision": 0.0}


def test_planted_rate_counts_audio_segments_the_generator_answered():
    """Own channel (PC-LH): one of the character's two clauses caused a left-hand gesture -> 1/2; a second
    gesture caused by the same clause counts once; the partner's clauses are not the character's."""
    from convsynth_jax.evaluation.annotation import planted_rate

    ev = pd.DataFrame([
        ("s", "a", "PC", 1.0, 2.5, "", np.nan), ("s", "a", "PC", 4.0, 5.0, "", np.nan),
        ("s", "b", "PC", 6.0, 7.0, "", np.nan),
        ("s", "a", "LH", 1.2, 1.8, "PC", 1.0), ("s", "a", "LH", 2.0, 2.4, "PC", 1.0),
        ("s", "b", "LH", 6.2, 6.8, "PC", 6.0)],
        columns=["session", "participant", "kind", "start", "end", "source", "cause_start"])
    assert planted_rate(ev, "a", "PC-LH") == 0.5
    assert planted_rate(ev, "b", "PC-LH") == 1.0
    assert planted_rate(ev[ev.kind != "LH"], "a", "PC-LH") == 0.0


def test_negative_controls_give_each_audio_motion_that_is_not_its_own(tiny_annotations):
    from convsynth_jax.evaluation.annotation import negative_control

    names = list(tiny_annotations)
    flat = [a for s in names for a in tiny_annotations[s].values()]
    shifted = negative_control(tiny_annotations, "shift")
    assert len(shifted) == len(flat)
    for orig, c in zip(flat, shifted):
        k = orig.motion.num_frames // 3
        np.testing.assert_array_equal(c.motion.rotations, np.roll(orig.motion.rotations, k, 0))
        assert c.segments is orig.segments                                  # the audio stays
    swapped = negative_control(tiny_annotations, "swap")
    role = next(iter(tiny_annotations[names[0]]))
    nxt = tiny_annotations[names[1 % len(names)]][role].motion
    n = min(nxt.num_frames, tiny_annotations[names[0]][role].motion.num_frames)
    np.testing.assert_array_equal(swapped[0].motion.rotations, nxt.rotations[:n])
    with pytest.raises(ValueError, match="negative control"):
        negative_control(tiny_annotations, "reverse")


def test_hand_decomposition_accounts_for_every_clause_and_detection(tiny_annotations, tiny_corpus_dir):
    """Per character and hand: caused = caused and detected + caused and missed, and every detection not
    caused by its clause is put in exactly one of the four explanations."""
    from convsynth_jax.annotate.params import AnnotateParams
    from convsynth_jax.evaluation.annotation import hand_decomposition

    ev = pd.read_csv(tiny_corpus_dir / "events.csv")
    glitches = pd.DataFrame(columns=["session", "participant", "joint", "start_frame", "end_frame"])
    out = hand_decomposition(tiny_annotations, ev, glitches, AnnotateParams())
    assert {h for _, h in out} == {"PC-LH", "PC-RH"}
    for c in out.values():
        assert c["caused_detected"] + c["caused_missed"] == c["caused"] <= c["clauses"]
        not_caused = sum(v for k, v in c.items() if k.startswith("not_caused_detected"))
        assert not_caused == c["detected"] - c["caused_detected"]
        assert c["not_caused_detected_glitch"] == 0                         # no glitches given
    assert sum(c["clauses"] for c in out.values()) > 0


def test_real_speech_scores_say_when_the_recordings_are_missing(tmp_path):
    from convsynth_jax.annotate.params import AnnotateParams
    from convsynth_jax.evaluation.annotation import real_speech_scores

    assert "not found" in real_speech_scores(tmp_path / "absent", AnnotateParams())["skipped"]


def test_fluent_clause_scores_score_every_clause_start_but_the_first():
    from convsynth_jax.annotate.params import AnnotateParams
    from convsynth_jax.evaluation.annotation import fluent_clause_scores

    out = fluent_clause_scores(1, AnnotateParams())
    assert set(out) == {AnnotateParams().clause_method, "pause"}
    for f in out.values():
        assert f["planted_boundaries"] == 6                                  # 7 clauses, the first start is not a boundary
        assert 0.0 <= f["boundary_recall"] <= 1.0 and 0.0 <= f["boundary_precision"] <= 1.0
