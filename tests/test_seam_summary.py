"""Seams of a collected leave-one-out run in both readings (convsynth_jax.evaluation.seam_summary), on a
small made-up run over the tiny corpus's recordings."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from convsynth_jax.evaluation.seam_summary import seam_readings, seam_run_summary, seam_summary_lines

FPS = 30.0


@pytest.fixture
def run_dir(tiny_annotations, tmp_path):
    session = sorted(tiny_annotations)[0]
    role = sorted(tiny_annotations[session])[0]
    rows = [  # window 0-4 s: a seam over 1 that its content alone explains; 4-8 s: a blend over its content; no seam
        dict(fold=0, condition="all", session=session, role=role, character="female", window_start=0.0, window_end=4.0,
             seam_ratio=1.5, seam_content_ratio=1.5, success=True, jerk=2.0, gt_jerk=1.0, num_synthetic_transitions=2),
        dict(fold=0, condition="all", session=session, role=role, character="female", window_start=4.0, window_end=8.0,
             seam_ratio=1.3, seam_content_ratio=0.5, success=True, jerk=2.0, gt_jerk=1.0, num_synthetic_transitions=4),
        dict(fold=0, condition="none", session=session, role=role, character="female", window_start=0.0, window_end=4.0,
             seam_ratio=np.nan, seam_content_ratio=np.nan, success=False, jerk=np.nan, gt_jerk=1.0, num_synthetic_transitions=0)]
    pd.DataFrame(rows).to_csv(tmp_path / "all_cases.csv", index=False)
    pd.DataFrame([("all", 2, 2), ("none", 0, 1)], columns=["condition", "solved_windows", "windows"]).to_csv(
        tmp_path / "success_rates.csv", index=False)
    pd.DataFrame([("all", "female", "PC-LH", 0.2, 0.6, 0.01), ("all", "female", "PC-RH", 0.5, 0.5, 0.9)],
                 columns=["condition", "character", "hypothesis", "synth_rate", "gt_rate", "p_value"]).to_csv(
        tmp_path / "cooccurrence_by_condition.csv", index=False)
    return tmp_path


def test_the_recording_reading_scales_the_window_reading(run_dir, tiny_annotations):
    s = seam_readings(pd.read_csv(run_dir / "all_cases.csv"), tiny_annotations, FPS)
    assert len(s) == 2                                                   # the window without a seam is left out
    assert (s["gt_recording_max"] >= s["gt_window_max"] - 1e-9).all()    # a window is part of its recording
    np.testing.assert_allclose(s["seam_ratio_recording"], s["seam_ratio"] * s["gt_window_max"] / s["gt_recording_max"])


def test_a_run_summary_attributes_seams_to_content_or_blend(run_dir, tiny_annotations):
    r = seam_run_summary("tiny", run_dir, tiny_annotations, FPS)
    assert (r["windows_with_transitions"], r["window_over_1"], r["window_worst"]) == (2, 2, 1.5)
    assert (r["over_1_content_at_least_1"], r["over_1_blend"]) == (1, 1)
    assert r["blend_worst"] == pytest.approx(1.3 / 0.5)
    assert r["success"] == {"all": "2/2", "none": "0/1"}
    assert r["cooccurrence_significant"] == {"all": ["female PC-LH 0.20 vs 0.60"]}
    assert r["mean_jerk_ratio"] == pytest.approx(2.0) and r["synthetic_transitions_per_window"] == pytest.approx(3.0)
    text = "\n".join(seam_summary_lines([r]))
    assert "| tiny | 2 | 2 / 1.50 / 1.40 |" in text and "| tiny | 2 | 1 | 1 | 2.60 |" in text
