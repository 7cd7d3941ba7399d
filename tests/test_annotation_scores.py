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
