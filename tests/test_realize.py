"""Realization's vectorized root integration against a plain per-frame loop (SciPy rotations)."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from convsynth_jax.data.skeleton_seated import seated_skeleton
from convsynth_jax.skeleton import Motion
from convsynth_jax.synth.realize import realize


def _loop_root(source_clips, source_frames, motions, chair, chair_yaw_deg):
    """The obvious version: one frame at a time, SciPy for every rotation."""
    def yaw(q):
        return 2.0 * np.arctan2(q[2], q[0])

    T = len(source_frames)
    vel, rate = np.zeros((T, 3)), np.zeros(T)
    for t, (c, f) in enumerate(zip(source_clips, source_frames)):
        m = motions[c]
        f0, f1 = (f, f + 1) if f + 1 < m.num_frames else (max(f - 1, 0), f)
        y0 = yaw(m.rotations[f0, 0])
        vel[t] = Rotation.from_rotvec([0, -y0, 0]).apply(m.translations[f1, 0] - m.translations[f0, 0])
        rate[t] = (yaw(m.rotations[f1, 0]) - y0 + np.pi) % (2 * np.pi) - np.pi
    heading = np.deg2rad(chair_yaw_deg) + np.concatenate([[0.0], np.cumsum(rate[:-1])])
    pos = np.zeros((T, 3))
    pos[0] = chair
    for t in range(1, T):
        pos[t] = pos[t - 1] + Rotation.from_rotvec([0, heading[t - 1], 0]).apply(vel[t - 1])
    rot = []
    for t, (c, f) in enumerate(zip(source_clips, source_frames)):
        q = motions[c].rotations[f, 0]
        src = Rotation.from_quat(q[[1, 2, 3, 0]])
        tilt = Rotation.from_rotvec([0, -yaw(q), 0]) * src
        rot.append((Rotation.from_rotvec([0, heading[t], 0]) * tilt).as_quat()[[3, 0, 1, 2]])
    return pos, np.array(rot)


def test_root_integration_equals_the_per_frame_loop():
    rng = np.random.default_rng(0)
    skel = seated_skeleton()
    J = skel.num_joints
    motions = {}
    for name in ("a", "b"):
        n = 40
        ang = np.cumsum(rng.normal(0, 0.05, n))  # a wandering heading with some tilt
        tilt = rng.normal(0, 0.1, n)
        rot = np.zeros((n, J, 4)); rot[..., 0] = 1
        r = Rotation.from_euler("YX", np.c_[ang, tilt]).as_quat()
        rot[:, 0] = r[:, [3, 0, 1, 2]]
        trans = np.broadcast_to(skel.offsets, (n, J, 3)).copy()
        trans[:, 0] = np.cumsum(rng.normal(0, 0.5, (n, 3)), axis=0)
        motions[name] = Motion(skel, rot, trans, 30.0, name)
    clips = ["a"] * 25 + ["b"] * 20
    frames = list(range(5, 30)) + list(range(10, 30))
    m = realize(clips, frames, motions, [25], chair=(1.0, 0.0, -60.0), chair_yaw_deg=180.0, blend_frames=0)
    pos, rot = _loop_root(clips, frames, motions, (1.0, 0.0, -60.0), 180.0)
    pos[:, 1] = [motions[c].translations[f, 0, 1] for c, f in zip(clips, frames)]
    np.testing.assert_allclose(m.translations[:, 0], pos, atol=1e-9)
    np.testing.assert_allclose(np.abs(np.sum(m.rotations[:, 0] * rot, -1)), 1.0, atol=1e-9)


def _angle(a, b):
    """Angle (radians) between unit quaternions, (..., 4)."""
    return 2.0 * np.arccos(np.clip(np.abs(np.sum(a * b, axis=-1)), 0.0, 1.0))


def _still_clip(skel, name, euler_deg, height, tilt_deg, n=40):
    """A motionless clip: every joint below the root at one rotation, the root at one height and tilt."""
    J = skel.num_joints
    rot = np.zeros((n, J, 4))
    rot[:, 1:] = Rotation.from_euler("XYZ", euler_deg, degrees=True).as_quat()[[3, 0, 1, 2]]
    rot[:, 0] = Rotation.from_euler("X", tilt_deg, degrees=True).as_quat()[[3, 0, 1, 2]]
    trans = np.broadcast_to(skel.offsets, (n, J, 3)).copy()
    trans[:, 0, 1] = height
    return Motion(skel, rot, trans, 30.0, name)


def test_back_to_back_transitions_do_not_pop():
    """Two synthetic transitions in consecutive frames (a -> b at 20, b -> c at 21): the displayed
    pose, the root's tilt and its height must move smoothly from a to c, no frame-to-frame step
    larger than a single cosine blend's steepest step (before: the second blend started from b's raw
    pose, so the joints jumped by the whole a-b difference in one frame, and tilt and height were
    not blended at all)."""
    skel = seated_skeleton()
    motions = {"a": _still_clip(skel, "a", (0, 0, 0), 90.0, 0.0), "b": _still_clip(skel, "b", (60, 0, 0), 80.0, 20.0),
               "c": _still_clip(skel, "c", (0, 0, 60), 100.0, -20.0)}
    clips = ["a"] * 20 + ["b"] + ["c"] * 19
    frames = list(range(20)) + [5] + list(range(5, 24))
    n = 6
    m = realize(clips, frames, motions, [20, 21], blend_frames=n)
    steepest = max(0.5 * np.pi / (n + 1) * np.sin(np.pi * x / (n + 1)) for x in np.linspace(0, n + 1, 200)) * 1.2
    joint_step = _angle(m.rotations[1:, 1:], m.rotations[:-1, 1:]).max()
    a_to_c = _angle(motions["a"].rotations[0, 1:], motions["c"].rotations[0, 1:]).max()
    assert joint_step <= steepest * a_to_c + 1e-9, (joint_step, steepest * a_to_c)
    tilt_step = _angle(m.rotations[1:, 0], m.rotations[:-1, 0]).max()
    assert tilt_step <= steepest * np.deg2rad(20.0) + 1e-9, np.rad2deg(tilt_step)
    height_step = np.abs(np.diff(m.translations[:, 0, 1])).max()
    assert height_step <= steepest * 10.0 + 1e-9, height_step
    # the blend ends on the new source: from frame 21 + n on the displayed pose is c's
    np.testing.assert_allclose(np.abs(np.sum(m.rotations[21 + n:, 1:] * motions["c"].rotations[0, 1:], -1)), 1.0,
                               atol=1e-9)
    np.testing.assert_allclose(m.translations[21 + n:, 0, 1], 100.0)


def test_a_single_transition_is_the_plain_cross_fade():
    """One transition: the previous clip's continuation slerped into the new source with cosine weights."""
    from convsynth_jax.rotations import quat_slerp_np
    from convsynth_jax.synth.realize import blend_weight

    rng = np.random.default_rng(1)
    skel = seated_skeleton()
    J = skel.num_joints
    motions = {}
    for name in ("a", "b"):
        r = Rotation.from_rotvec(rng.normal(0, 0.3, (40 * J, 3))).as_quat()[:, [3, 0, 1, 2]].reshape(40, J, 4)
        motions[name] = Motion(skel, r, np.broadcast_to(skel.offsets, (40, J, 3)).copy(), 30.0, name)
    clips, frames = ["a"] * 10 + ["b"] * 15, list(range(10)) + list(range(20, 35))
    m = realize(clips, frames, motions, [10], blend_frames=4)
    for k in range(4):
        want = quat_slerp_np(motions["a"].rotations[10 + k, 1:], motions["b"].rotations[20 + k, 1:],
                             np.full(J - 1, blend_weight(k, 4)))
        np.testing.assert_allclose(np.abs(np.sum(m.rotations[10 + k, 1:] * want, -1)), 1.0, atol=1e-9)
    np.testing.assert_allclose(np.abs(np.sum(m.rotations[14:, 1:] * motions["b"].rotations[24:35, 1:], -1)), 1.0,
                               atol=1e-9)


def test_quintic_decay_boundary_conditions():
    """The inertialization offset starts at x0 with slope v0 and ends at 0 with zero slope and
    acceleration at frame n (checked on the polynomial by finite differences of a fine grid)."""
    from convsynth_jax.synth.realize import quintic_decay

    x0, v0, n = np.array([2.0, -1.0]), np.array([0.5, 0.3]), 10
    np.testing.assert_allclose(quintic_decay(x0, v0, n, 0), x0)
    h = 1e-4
    f = lambda k: quintic_decay(x0, v0, n, k)  # noqa: E731
    np.testing.assert_allclose((f(h) - f(0)) / h, v0, atol=1e-3)
    np.testing.assert_allclose(f(n - h), 0.0, atol=1e-9)
    np.testing.assert_allclose((f(n - h) - f(n - 2 * h)) / h, 0.0, atol=1e-6)
    np.testing.assert_allclose(f(n), 0.0)


def test_inertialize_keeps_value_and_velocity_and_ends_on_the_source():
    """blend_method=inertialize: at a transition the displayed height and joint rotation continue the
    previous stream's last value and velocity (no step, no velocity jump), and from blend_frames
    after the transition the output is the new source exactly; a second transition one frame later
    composes (no step larger than the first one's)."""
    skel = seated_skeleton()
    J = skel.num_joints
    n = 50

    def moving(name, rate, h0):
        t = np.arange(n)
        rot = np.zeros((n, J, 4))
        rot[:, 1:] = Rotation.from_rotvec(np.c_[rate * t, 0 * t, 0 * t]).as_quat()[:, None, [3, 0, 1, 2]]
        rot[:, 0] = [1, 0, 0, 0]
        trans = np.broadcast_to(skel.offsets, (n, J, 3)).copy()
        trans[:, 0, 1] = h0 + 0.5 * rate * 10 * t
        return Motion(skel, rot, trans, 30.0, name)

    motions = {"a": moving("a", 0.02, 90.0), "b": moving("b", -0.03, 80.0), "c": moving("c", 0.0, 100.0)}
    clips, frames = ["a"] * 20 + ["b"] * 25, list(range(20)) + list(range(10, 35))
    m = realize(clips, frames, motions, [20], blend_frames=8, blend_method="inertialize")
    h = m.translations[:, 0, 1]
    # the value and velocity carried over: frame 20 extrapolates frames 18-19 of a
    assert h[20] == pytest.approx(2 * h[19] - h[18], abs=1e-9)
    ang = _angle(m.rotations[1:, 1], m.rotations[:-1, 1])
    assert ang[19] == pytest.approx(0.02, abs=1e-9)  # the step into frame 20 is a's own step
    np.testing.assert_allclose(h[28:], [motions["b"].translations[f, 0, 1] for f in frames[28:]], atol=1e-9)
    np.testing.assert_allclose(np.abs(np.sum(m.rotations[28:, 1:] * motions["b"].rotations[18:35, 1:], -1)), 1.0,
                               atol=1e-9)
    # back to back: a -> b at 20, b -> c at 21; no height step bigger than the largest source step
    clips2, frames2 = ["a"] * 20 + ["b"] + ["c"] * 24, list(range(20)) + [10] + list(range(10, 34))
    m2 = realize(clips2, frames2, motions, [20, 21], blend_frames=8, blend_method="inertialize")
    steps = np.abs(np.diff(m2.translations[:, 0, 1]))
    assert steps.max() <= 3.0, steps.max()  # the raw cut jumps 10-20 cm; the sources step 0.1-0.15 cm


def test_unknown_blend_method_is_a_config_error():
    from convsynth_jax.errors import ConfigError

    skel = seated_skeleton()
    m = _still_clip(skel, "a", (0, 0, 0), 90.0, 0.0)
    with pytest.raises(ConfigError, match="blend_method"):
        realize(["a"] * 5, list(range(5)), {"a": m}, [2], blend_frames=3, blend_method="spline")


def _spinning_clip(skel, name, deg_per_frame, n=60, start=5):
    """Every joint below the root turning about X at ``deg_per_frame``, at angle 0 at frame ``start``."""
    J = skel.num_joints
    ang = deg_per_frame * (np.arange(n) - start)
    rot = np.zeros((n, J, 4))
    rot[:, 1:] = Rotation.from_euler("X", ang[:, None], degrees=True).as_quat()[:, None, [3, 0, 1, 2]]
    rot[:, 0] = [1.0, 0.0, 0.0, 0.0]
    trans = np.broadcast_to(skel.offsets, (n, J, 3)).copy()
    trans[:, 0, 1] = 90.0
    return Motion(skel, rot, trans, 30.0, name)


def test_a_fast_clip_visited_for_one_frame_does_not_play_through_the_next_blend():
    """a -> b at 20 and b -> c at 21, where b turns every joint 10 degrees a frame and is displayed for
    one frame at the blend's first weight. The display must stay within that weight's share of b's
    excursion of the plain a -> c cross-fade (before: the second blend's old stream moved with b's own
    motion from the displayed pose, so b's turning played at full weight, fading over the blend:
    tens of degrees off, and a root-relative acceleration several times any source's)."""
    from convsynth_jax.rotations import quat_slerp_np
    from convsynth_jax.synth.realize import blend_weight

    skel = seated_skeleton()
    n = 12
    motions = {"a": _still_clip(skel, "a", (0, 0, 0), 90.0, 0.0), "b": _spinning_clip(skel, "b", 10.0),
               "c": _still_clip(skel, "c", (0, 0, 30), 90.0, 0.0)}
    clips = ["a"] * 20 + ["b"] + ["c"] * 25
    frames = list(range(20)) + [5] + list(range(5, 30))
    m = realize(clips, frames, motions, [20, 21], blend_frames=n)
    a_rot, c_rot = motions["a"].rotations[0, 1:], motions["c"].rotations[0, 1:]
    excursion = max(_angle(a_rot, motions["b"].rotations[f, 1:]).max() for f in range(5, 5 + n + 1))
    bound = blend_weight(0, n) * excursion + 1e-6
    for u in range(21, 21 + n):
        plain = quat_slerp_np(a_rot, c_rot, np.full(len(a_rot), blend_weight(u - 21, n)))
        dev = _angle(m.rotations[u, 1:], plain).max()
        assert dev <= bound, (u, np.rad2deg(dev), np.rad2deg(bound))
    np.testing.assert_allclose(np.abs(np.sum(m.rotations[21 + n:, 1:] * c_rot, -1)), 1.0, atol=1e-9)


def _with_glitch(m, joint: str, frames, degrees: float):
    """A copy of clip ``m`` with a marker-swap glitch: ``joint`` turned ``degrees`` about Z on ``frames``."""
    rot = np.array(m.rotations, copy=True)
    j = m.skeleton.names.index(joint)
    kick = Rotation.from_euler("Z", degrees, degrees=True)
    for f in frames:
        rot[f, j] = (kick * Rotation.from_quat(rot[f, j][[1, 2, 3, 0]])).as_quat()[[3, 0, 1, 2]]
    return Motion(m.skeleton, rot, np.array(m.translations), m.fps, m.name)


@pytest.mark.parametrize("nested", [False, True])
def test_a_blend_never_fades_in_a_glitch_of_its_continuation(nested):
    """A clip continued by a blend has a marker-swap glitch (29 degrees on the right arm for
    2 frames) right after the frames the path displays. ``nested``: the clip is an interrupted layer
    (a -> b at 20, b -> c at 28, b's glitch at its frames 12-13, played at b's frozen weight 0.68:
    what the nested blend did on leave-one-out); else the old stream of a single transition (a -> c at 20, a's glitch at 22-23).
    With the hold (synth.continuation_max_step_deg) the display equals that of the clean clip held
    at the frame before the glitch; without it the right arm jumps by a large part of 29 degrees."""
    skel = seated_skeleton()
    n = 12
    clean = {"a": _still_clip(skel, "a", (0, 0, 0), 90.0, 0.0), "b": _still_clip(skel, "b", (0, 0, 15), 90.0, 0.0),
             "c": _still_clip(skel, "c", (0, 0, 30), 90.0, 0.0)}
    if nested:   # b shown for 8 frames (weight 0.68 when interrupted), then continued from its frame 11
        clips, frames = ["a"] * 20 + ["b"] * 8 + ["c"] * 20, list(range(20)) + list(range(4, 12)) + list(range(20))
        syn, bad = [20, 28], ("b", [12, 13])
    else:
        clips, frames = ["a"] * 20 + ["c"] * 20, list(range(20)) + list(range(20))
        syn, bad = [20], ("a", [22, 23])
    glitched = dict(clean, **{bad[0]: _with_glitch(clean[bad[0]], "RightArm", bad[1], 29.0)})
    ref = realize(clips, frames, clean, syn, blend_frames=n)
    arm = skel.names.index("RightArm")
    off = realize(clips, frames, glitched, syn, blend_frames=n)
    assert np.rad2deg(_angle(off.rotations[:, arm], ref.rotations[:, arm]).max()) > 5.0   # the defect, unheld
    held = realize(clips, frames, glitched, syn, blend_frames=n, max_step_deg=15.0)
    # still clips: holding the clean clip changes nothing, so the held display is the clean one
    np.testing.assert_allclose(np.abs(np.sum(held.rotations * ref.rotations, -1)), 1.0, atol=1e-9)


def test_continuation_end_stops_before_the_first_large_step():
    from convsynth_jax.synth.realize import continuation_end

    skel = seated_skeleton()
    m = _with_glitch(_spinning_clip(skel, "s", 5.0, n=30), "RightArm", [12, 13], 29.0)
    assert continuation_end(m.rotations, 3, 15.0, 100) == 11       # 11 -> 12 turns 29 + 5 degrees
    assert continuation_end(m.rotations, 3, 0.0, 100) == 29         # off: the clip's last frame
    assert continuation_end(m.rotations, 3, 15.0, 5) == 8           # within the horizon
    assert continuation_end(m.rotations, 14, 15.0, 100) == 29       # after the glitch
    assert continuation_end(m.rotations, 12, 15.0, 100) == 13       # inside the glitch: stops before it ends


def test_continuation_end_from_a_clips_large_steps_agrees_with_the_direct_scan():
    """A realization computes each clip's large steps once; every (frame, horizon, limit) gives the same end."""
    from convsynth_jax.synth.realize import continuation_end, large_steps

    skel = seated_skeleton()
    m = _with_glitch(_spinning_clip(skel, "s", 5.0, n=60), "RightArm", [12, 13, 40], 29.0)
    for limit in (4.0, 15.0, 40.0):
        big = large_steps(m.rotations, limit)
        for frame in range(60):
            for horizon in (0, 1, 2, 5, 27, 100):
                assert continuation_end(m.rotations, frame, limit, horizon, big) == \
                    continuation_end(m.rotations, frame, limit, horizon), (limit, frame, horizon)


def test_blend_detail_keeps_the_new_sources_frame_to_frame_motion():
    """Two clips whose joint 1 trembles (+-0.01 rad a frame) in opposite phase at the frames a
    cross-fade mixes: the plain blend cancels the tremor mid-blend; with detail_frames 3 the blended
    frames keep the new source's steps. Frames outside the blend are the same either way."""
    skel = seated_skeleton()
    J = skel.num_joints
    motions = {}
    for name in ("a", "b"):
        ang = 0.004 * np.arange(60) + 0.01 * (-1.0) ** np.arange(60)
        rot = np.zeros((60, J, 4)); rot[..., 0] = 1
        rot[:, 1, 0], rot[:, 1, 1] = np.cos(ang / 2), np.sin(ang / 2)
        motions[name] = Motion(skel, rot, np.broadcast_to(skel.offsets, (60, J, 3)).copy(), 30.0, name)
    clips, frames = ["a"] * 10 + ["b"] * 30, list(range(10)) + list(range(21, 51))   # b at odd offset: opposite phase

    def steps(m):
        a = 2 * np.arctan2(m.rotations[:, 1, 1], m.rotations[:, 1, 0])
        return np.abs(np.diff(a))

    plain = realize(clips, frames, motions, [10], blend_frames=12)
    kept = realize(clips, frames, motions, [10], blend_frames=12, detail_frames=3)
    src = steps(motions["b"])[21:50].mean()
    assert steps(plain)[13:19].mean() < 0.6 * src and steps(kept)[13:19].mean() > 0.8 * src
    np.testing.assert_allclose(kept.rotations[:10], plain.rotations[:10], atol=1e-12)
    np.testing.assert_allclose(kept.rotations[22:], plain.rotations[22:], atol=1e-12)
