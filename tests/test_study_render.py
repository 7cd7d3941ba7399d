"""The study videos' rasterizer against a per-pixel reference, the three-quarter camera, frozen
bodies for attention checks, and the build's pure helpers (sweep filtering, pair checks)."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from convsynth_jax.errors import ConfigError
from convsynth_jax.study import render as R


def _capsule_reference(img, p0, p1, radius, rgb):
    """Per-pixel loops: distance from each pixel centre to the segment, one-pixel linear edge."""
    out = img.copy()
    for r in range(img.shape[0]):
        for c in range(img.shape[1]):
            x, y = c + 0.5, r + 0.5
            dx, dy = p1[0] - p0[0], p1[1] - p0[1]
            n2 = dx * dx + dy * dy
            t = 0.0 if n2 <= 1e-9 else min(max(((x - p0[0]) * dx + (y - p0[1]) * dy) / n2, 0.0), 1.0)
            d = np.hypot(x - (p0[0] + t * dx), y - (p0[1] + t * dy))
            a = min(max(radius + 0.5 - d, 0.0), 1.0)
            out[r, c] = out[r, c] * (1 - a) + a * np.asarray(rgb)
    return out


@pytest.mark.parametrize("p0,p1,radius", [((3.2, 4.7), (20.5, 15.1), 2.6), ((10.0, 10.0), (10.0, 10.0), 4.2),
                                          ((-3.0, 5.0), (8.0, 30.0), 1.0), ((12.0, 2.0), (12.0, 2.0), 0.4)])
def test_capsule_matches_the_per_pixel_reference(p0, p1, radius):
    rng = np.random.default_rng(0)
    img = rng.uniform(0, 255, (24, 28, 3)).astype(np.float32)
    rgb = np.array([10.0, 200.0, 90.0], np.float32)
    fast = img.copy()
    R._capsule(fast, p0, p1, radius, rgb)
    np.testing.assert_allclose(fast, _capsule_reference(img.astype(np.float64), p0, p1, radius, rgb), atol=1e-3)


def _two_bodies(frames=4):
    from convsynth_jax.testing.study import _stick_body

    return [_stick_body(-0.6, frames, 0.0), _stick_body(0.6, frames, 1.0)]


def test_three_quarter_camera_turns_the_side_view_and_fits_the_panel():
    bodies = _two_bodies()
    side = R.three_quarter_camera(bodies, 100, 120, yaw_deg=0.0, pitch_deg=0.0)
    np.testing.assert_allclose(side.right, [1, 0, 0], atol=1e-12)          # roots spread along X
    np.testing.assert_allclose(np.cross(side.right, side.up), -side.view, atol=1e-12)   # not mirrored
    tq = R.three_quarter_camera(bodies, 100, 120)
    assert abs(tq.view @ np.array([1.0, 0, 0])) > 0.5 and tq.view[1] < 0    # turned towards the characters, looking down
    for b in bodies:
        col, row, _ = R._project(tq, b.positions.reshape(-1, 3), 100, 120)
        assert col.min() >= 0 and col.max() <= 100 and row.min() >= 0 and row.max() <= 120


def test_frames_are_even_sized_and_a_frozen_body_does_not_move():
    bodies = _two_bodies(6)
    still = [R.frozen(b) for b in bodies]
    frames = list(R.side_by_side_frames(bodies, still, 40, 48))
    assert len(frames) == 6 and frames[0].shape == (48, 82, 3) and frames[0].dtype == np.uint8
    right = [f[:, 42:] for f in frames]
    left = [f[:, :40] for f in frames]
    assert all((r == right[0]).all() for r in right)
    assert any((x != left[0]).any() for x in left)
    with pytest.raises(Exception, match="even"):
        R.render_pair_video(bodies, still, 30.0, "x.mp4", width=41, height=48)


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
