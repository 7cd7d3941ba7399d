"""The study build's pure helpers (sweep filtering, pair checks). Its videos are drawn by the one
renderer, tested in tests/test_render.py."""
from __future__ import annotations

import pandas as pd
import pytest

from convsynth_jax.errors import ConfigError


def test_solved_in_sweep_needs_every_condition_and_both_characters():
    from convsynth_jax.study.build import solved_in_sweep

    rows = []
    for w in range(3):
        for cond in ("all", "none", "no_lr"):
            for ch in ("f", "m"):
                ok = not (w == 1 and cond == "none" and ch == "m")
                rows.append({"session": "s1", "window": w, "condition": cond, "character": ch, "success": ok})
    cases = pd.DataFrame(rows[:-2])        # window 2 lacks no_lr
    assert solved_in_sweep(cases, ["all", "none", "no_lr"]) == {("s1", 0)}
    assert solved_in_sweep(cases, ["all"]) == {("s1", 0), ("s1", 1), ("s1", 2)}
    with pytest.raises(ConfigError, match="columns"):
        solved_in_sweep(cases.drop(columns="success"), ["all"])


def test_study_build_refuses_a_pair_with_an_unknown_condition(tmp_path):
    from convsynth_jax.config import compose, run_task

    with pytest.raises(ConfigError, match="not a condition"):
        run_task(compose(["task=study_build", "corpus=synthetic_tiny", "task.pairs=[{name: x, a: all, b: no_such}]"]), tmp_path)
    with pytest.raises(ConfigError, match="attention"):
        run_task(compose(["task=study_build", "task.attention_stimuli=1", "task.attention_per_participant=2"]), tmp_path)
