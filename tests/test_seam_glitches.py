"""The seam/glitch detector (convsynth_jax/synth/seam_glitches.py, run over a sweep by
the retired diagnosis seam_glitches.py, in git at e1848f1) flags a planted glitch that a blend fades in, and not the same
seam once the continuation holds (the control of the glitch detector's leave-one-out evidence)."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.transform import Rotation

from convsynth_jax.data.skeleton_seated import seated_skeleton
from convsynth_jax.errors import MissingFileError
from convsynth_jax.evaluation.metrics import seam_ratio
from convsynth_jax.kinematics import forward_kinematics
from convsynth_jax.skeleton import Motion
from convsynth_jax.synth.realize import realize
from convsynth_jax.synth.seam_glitches import (glitch_frames, nested_span, seam_glitch_counts, touching_rows,
                                               window_seam_glitches)
from test_realize import _with_glitch as _glitch  # one planted marker swap for the glitch tests

def _clip(skel, name, z_deg, n=40, spin=0.0):
    """Every joint below the root at ``z_deg`` about Z plus ``spin`` degrees a frame about X."""
    J = skel.num_joints
    rot = np.zeros((n, J, 4))
    for f in range(n):
        rot[f, 1:] = Rotation.from_euler("ZX", [z_deg, spin * f], degrees=True).as_quat()[[3, 0, 1, 2]]
    rot[:, 0] = [1.0, 0.0, 0.0, 0.0]
    trans = np.broadcast_to(skel.offsets, (n, J, 3)).copy()
    trans[:, 0, 1] = 90.0
    return Motion(skel, rot, trans, 30.0, name)


def test_detector_flags_a_faded_in_glitch_and_not_a_held_one():
    """The nested blend (a -> b at 20, b -> c at 28; b continued from its frame 11 through
    a 29-degree glitch at its frames 12-13). Unheld: the seam at 28 touches the glitch and is sharper
    than with the hold, where it no longer touches it (the nominal span still does)."""
    skel = seated_skeleton()
    B = 12
    motions = {"a": _clip(skel, "a", 0.0), "b": _glitch(_clip(skel, "b", 15.0), "RightArm", [12, 13], 29.0),
               "c": _clip(skel, "c", 30.0)}
    clips = ["a"] * 20 + ["b"] * 8 + ["c"] * 20
    frames = list(range(20)) + list(range(4, 12)) + list(range(20))
    glitches = {"b": {12, 13}}
    gt = _clip(skel, "gt", 0.0, n=len(frames), spin=1.0)
    out = {}
    for step in (0.0, 15.0):
        m = realize(clips, frames, motions, [20, 28], blend_frames=B, max_step_deg=step)
        res = SimpleNamespace(source_clip=clips, source_frame=np.array(frames), synthetic_at=[20, 28],
                              blend_frames=B, motion=m)
        pos, ref = (np.asarray(forward_kinematics(x), np.float64) for x in (m, gt))
        out[step] = window_seam_glitches(res, motions, glitches, step, lambda t: seam_ratio(pos, ref, 30.0, [t]))
    (off, n_off), (on, n_on) = out[0.0], out[15.0]
    assert [s["t"] for s in off] == [20, 28] and n_off == n_on == 0    # the path itself plays no glitch frame
    assert off[1]["touches_glitch_played"] and off[1]["glitch_continuation_played"] == "12;13"
    assert not on[1]["touches_glitch_played"] and on[1]["touches_glitch_nominal"]
    assert not off[0]["touches_glitch_played"]                           # a's continuation is clean
    assert off[1]["seam_ratio"] > 2 * on[1]["seam_ratio"]
    key = {"fold": 0, "condition": "all", "character": "x", "window": 0}
    rows = touching_rows(pd.DataFrame([{**key, **s} for s in off]), B, 3)
    assert [(r["where"], r["frame"], r["offset"], r["in_seam_measure"]) for r in rows] == [
        ("continuation", 12, 0, True), ("continuation", 13, 1, True)]
    held = touching_rows(pd.DataFrame([{**key, **s} for s in on]), B, 3)
    assert {r["where"] for r in held} == {"continuation, held (not played)"}
    assert seam_glitch_counts(pd.DataFrame(off)) == {"seams_total": 2, "seams_touching_glitch_played": 1,
                                                     "seams_touching_glitch_nominal": 1,
                                                     "seams_with_glitch_in_raw_sources": 0,
                                                     "seams_over_1": int(sum(s["seam_ratio"] > 1 for s in off))}


def test_frames_played_from_a_glitch_are_counted():
    skel = seated_skeleton()
    motions = {"a": _clip(skel, "a", 0.0)}
    res = SimpleNamespace(source_clip=["a"] * 10, source_frame=np.arange(10), synthetic_at=[], blend_frames=12,
                          motion=motions["a"].slice(0, 10))
    seams, n = window_seam_glitches(res, motions, {"a": {3, 4, 30}}, 0.0, lambda t: 1 / 0)
    assert seams == [] and n == 2                                        # no seam: the measure is not called


def test_nested_span_extends_a_blend_by_each_transition_inside_it():
    assert nested_span([20, 28], 0, 12) == 20          # 28 arrives before 20's blend ends at 32: until 40
    assert nested_span([20, 28], 1, 12) == 12
    assert nested_span([20, 32, 50], 0, 12) == 12      # 32: the blend has ended
    assert nested_span([5, 10, 15, 40], 0, 6) == 16


def test_glitch_frames_reads_glitches_csv_and_names_a_bad_file(tmp_path):
    p = tmp_path / "glitches.csv"
    pd.DataFrame({"session": ["s01", "s01", "s02"], "participant": ["A", "A", "B"], "kind": ["swap"] * 3,
                  "start_frame": [3, 10, 0], "end_frame": [5, 11, 2]}).to_csv(p, index=False)
    assert glitch_frames(p, lambda s, r: f"{s}_{r}") == {"s01_A": {3, 4, 10}, "s02_B": {0, 1}}
    with pytest.raises(MissingFileError, match="no glitches.csv"):
        glitch_frames(tmp_path / "none.csv", lambda s, r: s)
    pd.DataFrame({"session": ["s01"], "start_frame": [1]}).to_csv(p, index=False)
    with pytest.raises(MissingFileError, match=r"glitches.csv lacks the columns \['participant', 'end_frame'\]"):
        glitch_frames(p, lambda s, r: s)
