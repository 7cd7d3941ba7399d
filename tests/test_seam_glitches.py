"""experiments/analysis/seam_glitches.py: its seam/glitch detector flags a planted glitch that a blend
fades in, and not the same seam once the continuation holds (the control of the glitch detector's
leave-one-out evidence)."""
from __future__ import annotations

import importlib.util
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation

from convsynth_jax.data.skeleton_seated import seated_skeleton
from convsynth_jax.skeleton import Motion
from convsynth_jax.synth.realize import realize
from test_realize import _with_glitch as _glitch  # one planted marker swap for the glitch tests

SCRIPT = Path(__file__).resolve().parents[1] / "experiments" / "analysis" / "seam_glitches.py"


def _script():
    spec = importlib.util.spec_from_file_location("seam_glitches_script", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


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
    mod = _script()
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
        out[step] = mod.window_seams(res, gt, motions, glitches, step, 30.0)
    (off, n_off), (on, n_on) = out[0.0], out[15.0]
    assert [s["t"] for s in off] == [20, 28] and n_off == n_on == 0    # the path itself plays no glitch frame
    assert off[1]["touches_glitch_played"] and off[1]["glitch_continuation_played"] == "12;13"
    assert not on[1]["touches_glitch_played"] and on[1]["touches_glitch_nominal"]
    assert not off[0]["touches_glitch_played"]                           # a's continuation is clean
    assert off[1]["seam_ratio"] > 2 * on[1]["seam_ratio"]
    key = {"fold": 0, "condition": "all", "character": "x", "window": 0}
    rows = mod.touching_rows(pd.DataFrame([{**key, **s} for s in off]), B, 3)
    assert [(r["where"], r["frame"], r["offset"], r["in_seam_measure"]) for r in rows] == [
        ("continuation", 12, 0, True), ("continuation", 13, 1, True)]
    held = mod.touching_rows(pd.DataFrame([{**key, **s} for s in on]), B, 3)
    assert {r["where"] for r in held} == {"continuation, held (not played)"}


def test_frames_played_from_a_glitch_are_counted():
    mod = _script()
    skel = seated_skeleton()
    motions = {"a": _clip(skel, "a", 0.0)}
    res = SimpleNamespace(source_clip=["a"] * 10, source_frame=np.arange(10), synthetic_at=[], blend_frames=12,
                          motion=motions["a"].slice(0, 10))
    seams, n = mod.window_seams(res, motions["a"].slice(0, 10), motions, {"a": {3, 4, 30}}, 0.0, 30.0)
    assert seams == [] and n == 2
