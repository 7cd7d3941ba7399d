"""Walk the Talk core: planted-truth tests of contacts, loops, phases, Eq. 1-2, stylization, the
shift rule and the elbow bounce, each fast kernel against a slow NumPy reference."""
from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

from convsynth_jax.errors import ConvSynthError, WalkTalkError
from convsynth_jax.kinematics import forward_kinematics_np
from convsynth_jax.walktalk.body import check_same_skeleton, find_body
from convsynth_jax.walktalk.gestures import (
    Phases,
    check_standing,
    detect_phases,
    make_gesture,
    validate_phases,
)
from convsynth_jax.walktalk.locomotion import (
    detect_gait,
    extract_loop,
    seam_correct,
    tile_contact,
    tile_loop,
)
from convsynth_jax.walktalk.params import (
    GaitParams,
    GazeParams,
    PhaseParams,
    SpliceParams,
)
from convsynth_jax.walktalk.pipeline import (
    gesture_context,
    loop_context,
    splice_gesture,
)
from convsynth_jax.walktalk.splice import (
    joint_euler,
    splice_arrays,
    splice_weights,
    stylize,
)
from convsynth_jax.walktalk.sync import align_kernel, align_peak, nominal_frame
from convsynth_jax.walktalk.planted_clips import synthetic_gesture, synthetic_jog

TOL_Q = 2e-6   # float32 splice kernel vs float64 reference (quaternion components)


@pytest.fixture(scope="module")
def jog():
    return synthetic_jog(periods=3.5)


@pytest.fixture(scope="module")
def loop(jog):
    return extract_loop(jog[0], GaitParams())


# ---------------------------------------------------------------- locomotion


def test_contacts_and_strikes_match_planted_truth(jog):
    m, truth = jog
    g = detect_gait(m, GaitParams())
    assert g.gait == "jog"
    assert g.strikes_l == truth["strikes_l"] and g.strikes_r == truth["strikes_r"]
    np.testing.assert_array_equal(g.down_l, truth["down_l"])
    np.testing.assert_array_equal(g.contact, truth["contact"])


def test_loop_is_two_cycles_from_left_contact(jog, loop):
    m, truth = jog
    assert loop.start in truth["strikes_l"]
    assert loop.num_frames == 60  # two 30-frame cycles
    np.testing.assert_array_equal(loop.contact, truth["contact"][loop.start:loop.start + 60])
    np.testing.assert_allclose(loop.advance, [0, 0, 600.0])
    # the synthetic clip is exactly periodic: tiling reproduces the source clip
    tiled = tile_loop(loop, 45)
    np.testing.assert_allclose(tiled.rotations, m.rotations[loop.start:loop.start + 45], atol=1e-12)
    p_t, p_s = forward_kinematics_np(tiled), forward_kinematics_np(m.slice(loop.start, loop.start + 45))
    np.testing.assert_allclose(p_t, p_s, atol=1e-9)
    np.testing.assert_array_equal(tile_contact(loop, 150)[60:120], loop.contact)


def test_seam_correct_against_scipy_slerp():
    rng = np.random.default_rng(1)
    q = Rotation.random(13 * 3, random_state=2).as_quat().reshape(13, 3, 4)[..., [3, 0, 1, 2]]
    out = seam_correct(q)
    n = 12
    for j in range(3):
        r0 = Rotation.from_quat(q[0, j, [1, 2, 3, 0]])
        rn = Rotation.from_quat(q[n, j, [1, 2, 3, 0]])
        resid = r0 * rn.inv()
        sl = Slerp([0.0, 1.0], Rotation.concatenate([Rotation.identity(), resid]))
        for i in range(n):
            ref = (sl([i / n])[0] * Rotation.from_quat(q[i, j, [1, 2, 3, 0]])).as_quat()
            got = out[i, j, [1, 2, 3, 0]]
            assert min(np.abs(ref - got).max(), np.abs(ref + got).max()) < 1e-9
        # the virtual frame N after correction equals frame 0
        full = (resid * rn).as_quat()
        assert min(np.abs(full - q[0, j, [1, 2, 3, 0]]).max(), np.abs(full + q[0, j, [1, 2, 3, 0]]).max()) < 1e-9
    assert rng is not None


def test_too_few_cycles_lists_strikes(jog):
    short = jog[0].slice(0, 70)
    with pytest.raises(WalkTalkError) as e:
        extract_loop(short, GaitParams())
    assert "left heel strikes at frames [30, 60]" in str(e.value)
    assert "synthetic_jog" in str(e.value) and "frames 0-69" in str(e.value)


# ---------------------------------------------------------------- gestures


def test_phases_of_planted_gesture():
    m = synthetic_gesture(n=70, rise=(10, 25), fall=(40, 55))
    ph, hand = detect_phases(m, PhaseParams())
    assert hand == "r"
    # planted: motion starts after frame 10, the arm is up from 25 to 40, back at rest at 55
    assert 10 <= ph.pb < ph.sb <= 25 and 40 <= ph.se < ph.re <= 55
    assert len(ph.peaks) == 1 and 25 <= ph.peaks[0] <= 40
    wave, hand2 = detect_phases(synthetic_gesture(sides="both", oscillations=3), PhaseParams())
    assert hand2 == "both" and len(wave.peaks) >= 2


def test_phase_errors():
    with pytest.raises(WalkTalkError, match="out of order"):
        validate_phases(Phases(5, 12, 10, 20, 21, 30, (15,)), 40, "g.bvh")
    with pytest.raises(WalkTalkError, match="outside the stroke"):
        validate_phases(Phases(5, 9, 10, 20, 21, 30, (25,)), 40, "g.bvh")
    travelling = synthetic_gesture(travel_cm=100.0)
    with pytest.raises(WalkTalkError, match="not standing") as e:
        check_standing(travelling, GaitParams())
    assert "frame" in str(e.value) and travelling.name in str(e.value)
    assert issubclass(WalkTalkError, ConvSynthError)


def test_mismatched_joints_listed(jog):
    m = jog[0]
    sk = m.skeleton
    names = tuple("Wrist_R" if n == "Hand_R" else n for n in sk.names)
    other = dataclasses.replace(sk, names=names)
    with pytest.raises(WalkTalkError) as e:
        check_same_skeleton(sk, other, "loop.bvh", "gesture.bvh")
    assert "missing joints ['Hand_R']" in str(e.value) and "extra joints ['Wrist_R']" in str(e.value)
    with pytest.raises(WalkTalkError, match="hand_r"):
        find_body(other, "gesture.bvh")


# ---------------------------------------------------------------- Eq. 1-2


def test_splice_weights_eq2_exact():
    ph = Phases(10, 13, 14, 20, 21, 24, (17,))
    w = splice_weights(30, ph)
    expect = np.zeros(30)
    expect[10:14] = [0, 1 / 4, 2 / 4, 3 / 4]         # (t - Pb) / (Pe - Pb + 1)
    expect[14:21] = 1.0                              # stroke and holds: the gesture
    expect[21:25] = [3 / 4, 2 / 4, 1 / 4, 0]         # back to the locomotion by t_Re
    np.testing.assert_allclose(w, expect, atol=0)


def _slerp_ref(a, b, t):
    """Slow reference: explicit slerp along the shorter arc, one pair at a time."""
    if np.dot(a, b) < 0:
        b = -b
    d = np.clip(np.dot(a, b), -1, 1)
    th = np.arccos(d)
    if np.sin(th) < 1e-6:
        out = (1 - t) * a + t * b
    else:
        out = (np.sin((1 - t) * th) * a + np.sin(t * th) * b) / np.sin(th)
    return out / np.linalg.norm(out)


def test_splice_kernel_matches_numpy_reference():
    rng = np.random.default_rng(3)
    T, J = 37, 6
    lq = Rotation.random(T * J, random_state=4).as_quat().reshape(T, J, 4)
    gq = Rotation.random(T * J, random_state=5).as_quat().reshape(T, J, 4)
    w = rng.uniform(0, 1, T)
    w[:5] = 0
    w[10:15] = 1
    arm = np.array([False, True, True, False, True, False])
    out = splice_arrays(lq, gq, w, arm)
    for t in range(T):
        for j in range(J):
            ref = _slerp_ref(lq[t, j], gq[t, j], w[t]) if (arm[j] and w[t] > 0) else lq[t, j]
            assert min(np.abs(out[t, j] - ref).max(), np.abs(out[t, j] + ref).max()) < TOL_Q


def test_splice_end_to_end_eq1_eq2(loop):
    body = find_body(loop.motion.skeleton)
    lc = loop_context(loop, body)
    gm = synthetic_gesture(n=70)
    g = make_gesture(gm, GaitParams(), PhaseParams())
    gc = gesture_context(g, body)
    T = 180
    r = splice_gesture(lc, gc, 3.0, T, SpliceParams(), "naive")
    loco = tile_loop(loop, T)
    ph = r.phases
    arm = list(body.arm_r)
    other = [j for j in range(22) if j not in arm]
    # Eq. 1: lower body, torso (and the idle arm) are the locomotion's, feet identical
    np.testing.assert_allclose(r.motion.rotations[:, other], loco.rotations[:, other], atol=1e-7)
    np.testing.assert_allclose(r.motion.translations, loco.translations, atol=0)
    pos, pos_l = forward_kinematics_np(r.motion), forward_kinematics_np(loco)
    for key in ("foot_l", "foot_r", "toes_l", "toes_r"):
        np.testing.assert_allclose(pos[:, body.joints[key]], pos_l[:, body.joints[key]], atol=1e-4)
    # Eq. 2: outside the gesture the loop's arm, in the stroke the gesture's arm
    out = np.r_[0:ph.pb, ph.re + 1:T]
    np.testing.assert_allclose(r.motion.rotations[out][:, arm], loco.rotations[out][:, arm], atol=1e-7)
    for t in range(ph.sb, ph.se + 1):
        np.testing.assert_allclose(np.abs(np.sum(r.motion.rotations[t, arm] * gm.rotations[t - r.offset, arm], -1)),
                                   1.0, atol=1e-6)
    # the retraction ends on the locomotion (Eq. 2 as printed would end on the gesture)
    np.testing.assert_allclose(r.motion.rotations[ph.re, arm], loco.rotations[ph.re, arm], atol=1e-7)


# ---------------------------------------------------------------- stylization


def _stylize_ref(ge, b_l, sd, b_g, c):
    out = np.empty_like(ge)
    F, A, _ = ge.shape
    for a in range(A):
        for d in range(3):
            dev = [ge[f, a, d] + (b_l[a, d] - b_g[a, d]) - b_l[a, d] for f in range(F)]
            m = max(abs(x) for x in dev)
            s = 1.0 if m <= c * sd[a, d] else c * sd[a, d] / m
            for f in range(F):
                out[f, a, d] = b_l[a, d] + s * dev[f]
    return out


def test_stylize_kernel_vs_reference_and_bounds():
    from convsynth_jax.walktalk.splice import LoopStats

    rng = np.random.default_rng(7)
    ge = rng.normal(0, 1.0, (23, 4, 3))
    b_l, sd, b_g = rng.normal(0, 1, (4, 3)), rng.uniform(0.05, 0.6, (4, 3)), rng.normal(0, 1, (4, 3))
    for c in (0.5, 3.0, 100.0):
        got = stylize(ge, LoopStats(b_l, sd), b_g, c)
        ref = _stylize_ref(ge, b_l, sd, b_g, c)
        np.testing.assert_allclose(got, ref, atol=1e-5)
        assert np.all(np.abs(got - b_l) <= c * sd + 1e-5)
    # planted: one DOF deviating by 10 with std 1 and c 3 is rescaled to 3 (not clipped: the
    # half-way frame keeps half of it); a DOF inside the band is only offset by B_D
    ge2 = np.zeros((3, 1, 3))
    ge2[:, 0, 0] = [0.0, 5.0, 10.0]
    ge2[:, 0, 1] = [0.0, 0.5, 1.0]
    got = stylize(ge2, LoopStats(np.full((1, 3), 2.0), np.ones((1, 3))), np.zeros((1, 3)), 3.0)
    np.testing.assert_allclose(got[:, 0, 0], [2.0, 3.5, 5.0], atol=1e-6)
    np.testing.assert_allclose(got[:, 0, 1], [2.0, 2.5, 3.0], atol=1e-6)


def test_parameter_errors():
    with pytest.raises(WalkTalkError, match="c must be > 0"):
        SpliceParams(c=0.0)
    with pytest.raises(WalkTalkError, match=r"\[0, 1\]"):
        GazeParams(r_min=-0.1)
    with pytest.raises(WalkTalkError, match=r"\[0, 1\]"):
        GazeParams(r_max=1.5)


# ---------------------------------------------------------------- synchronization


def test_shift_rule_planted():
    contact = np.array([1, 1, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0], bool)
    assert align_peak(1, contact, 18, False) == 0          # already in contact
    assert align_peak(10, contact, 18, False) == -3        # nearest earlier contact frame 7
    assert align_peak(5, contact, 18, False) == -4         # frame 1
    assert align_peak(29, contact, 18, False) == 0         # none within 0.6 s: stays
    assert align_peak(10, contact, 18, True) == 0          # multi-peak gestures are not realigned
    assert align_peak(10, contact, 2, False) == 0          # search limited to max shift
    rng = np.random.default_rng(0)
    c = rng.uniform(size=200) < 0.3
    nom = rng.integers(0, 200, 64)
    multi = rng.uniform(size=64) < 0.2
    got = np.asarray(align_kernel(nom, c, multi, max_shift_frames=18))
    ref = [align_peak(int(n), c, 18, bool(mu)) for n, mu in zip(nom, multi)]
    np.testing.assert_array_equal(got, ref)
    assert np.all(got <= 0) and np.all(got >= -18)


def test_utterance_outside_timeline():
    with pytest.raises(WalkTalkError, match="outside the timeline"):
        nominal_frame(12.0, 0.2, 30.0, 300)
    with pytest.raises(WalkTalkError, match="outside the timeline"):
        nominal_frame(0.1, 0.2, 30.0, 300)
    assert nominal_frame(1.0, 0.2, 30.0, 300) == 24


def test_synced_peak_in_contact_and_before_utterance(loop):
    body = find_body(loop.motion.skeleton)
    lc = loop_context(loop, body)
    gc = gesture_context(make_gesture(synthetic_gesture(), GaitParams(), PhaseParams()), body)
    p = SpliceParams()
    for u in np.linspace(2.2, 4.0, 25):
        r = splice_gesture(lc, gc, float(u), 200, p, "stylized+synced")
        assert -0.6 - 1e-9 <= r.shift_s <= 0
        assert r.peak / 30.0 <= u
        assert r.contact[r.peak] or not r.contact[r.nominal_peak - 18:r.nominal_peak + 1].any()


def test_elbow_bounce_exact(loop):
    """R'_elbow = R_elbow + k dH_root: the spliced forearm DOF in the stroke differs from the
    unbounced stylized one by exactly k * (root height - its loop mean)."""
    body = find_body(loop.motion.skeleton)
    lc = loop_context(loop, body)
    gc = gesture_context(make_gesture(synthetic_gesture(), GaitParams(), PhaseParams()), body)
    k = 2.0
    p = SpliceParams(k_bounce=k)
    always = np.ones(200, bool)  # all contact: the synced splice is not shifted, same frames
    loco = tile_loop(loop, 200)
    a = splice_gesture(lc, gc, 3.0, 200, p, "stylized", loco=loco, contact=always)
    b = splice_gesture(lc, gc, 3.0, 200, p, "stylized+synced", loco=loco, contact=always)
    assert a.offset == b.offset
    elbow = body.joints["elbow_r"]
    dof = lc.elbow_dof["r"]
    ea = joint_euler(a.motion, (elbow,))[:, 0, dof]
    eb = joint_euler(b.motion, (elbow,))[:, 0, dof]
    h = loop.root_height
    ph = a.phases
    for t in range(ph.sb, ph.se + 1):
        dh = h[t % loop.num_frames] - h.mean()
        assert abs((eb[t] - ea[t]) - np.radians(k * dh)) < 1e-5
    assert np.ptp(h) > 5  # the planted bounce is there to see


# ---------------------------------------------------------------- references of helpers


def test_numpy_fk_matches_project_fk(jog):
    from convsynth_jax.kinematics import forward_kinematics

    m = jog[0].slice(0, 20)
    np.testing.assert_allclose(forward_kinematics_np(m), np.asarray(forward_kinematics(m)), atol=1e-3)


def test_quat_to_euler_matches_scipy_and_joint_euler(jog):
    import jax.numpy as jnp

    from convsynth_jax.rotations import euler_to_quat, quat_to_euler

    rng = np.random.default_rng(5)
    for order in ("XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"):
        e = rng.uniform(-1.4, 1.4, (50, 3))
        q = np.asarray(euler_to_quat(jnp.asarray(e), order), dtype=np.float64)
        got = np.asarray(quat_to_euler(jnp.asarray(q), order))
        ref = Rotation.from_quat(q[:, [1, 2, 3, 0]]).as_euler(order)
        np.testing.assert_allclose(got, ref, atol=1e-5)
    m = jog[0]
    je = joint_euler(m, (8,))[:, 0]
    np.testing.assert_allclose(je, np.asarray(quat_to_euler(jnp.asarray(m.rotations[:, 8]), "ZXY")), atol=1e-5)


def test_smootherstep_ease_and_transition_pad():
    from convsynth_jax.walktalk.pipeline import pad_gesture

    ph = Phases(10, 13, 14, 20, 21, 24, (17,))
    lin = splice_weights(30, ph, "linear")
    sm = splice_weights(30, ph, "smootherstep")
    np.testing.assert_allclose(sm, 6 * lin**5 - 15 * lin**4 + 10 * lin**3, atol=1e-12)
    assert sm[9] == 0 and sm[14] == 1 and sm[20] == 1 and sm[24] == 0
    with pytest.raises(WalkTalkError, match="unknown ease"):
        splice_weights(30, ph, "cubic")
    g = make_gesture(synthetic_gesture(n=70), GaitParams(), PhaseParams())
    gp = pad_gesture(g, 5)
    assert gp.motion.num_frames == 80
    assert (gp.phases.pb, gp.phases.sb, gp.phases.se, gp.phases.re) == (g.phases.pb, g.phases.sb + 5, g.phases.se + 5, g.phases.re + 10)
    assert gp.phases.peaks == (g.phases.peaks[0] + 5,)
    np.testing.assert_array_equal(gp.motion.rotations[:5], np.repeat(g.motion.rotations[:1], 5, 0))
    np.testing.assert_array_equal(gp.motion.rotations[5:75], g.motion.rotations)


def test_stylize_respects_joint_limits_planted():
    """Planted: B_L = 2 with std 1 and c 3 allows 2 - 3 = -1, but the range of motion ends at 0.5
    (ref 2, lo -1.5, hi 10): the deviation (0 .. -10) is rescaled linearly by 1.5 / 10 so the DOF
    ends on 0.5, not clipped and not at the paper's -1; the other side keeps the c-sigma band."""
    from convsynth_jax.walktalk.splice import JointLimits, LoopStats, stylize_bands

    ge = np.zeros((3, 1, 3))
    ge[:, 0, 0] = [0.0, -5.0, -10.0]
    ge[:, 0, 1] = [0.0, 5.0, 10.0]
    stats = LoopStats(np.full((1, 3), 2.0), np.ones((1, 3)))
    lim = JointLimits((7,), np.full((1, 3), 2.0), np.full((1, 3), -1.5), np.full((1, 3), 10.0))
    down, up = stylize_bands(stats, 3.0, lim, (7,))
    np.testing.assert_allclose(down[0], 1.5)
    np.testing.assert_allclose(up[0], 3.0)
    got = stylize(ge, stats, np.zeros((1, 3)), 3.0, lim, (7,))
    np.testing.assert_allclose(got[:, 0, 0], [2.0, 1.25, 0.5], atol=1e-6)
    np.testing.assert_allclose(got[:, 0, 1], [2.0, 3.5, 5.0], atol=1e-6)
    loose = JointLimits((7,), lim.ref, lim.lo - 1e-6, lim.hi + 1e-6)   # float32 kernel on the limit
    assert not loose.violations(got, (7,)).any()
    paper = stylize(ge, stats, np.zeros((1, 3)), 3.0)             # the paper's band alone
    np.testing.assert_allclose(paper[:, 0, 0], [2.0, 0.5, -1.0], atol=1e-6)
    assert loose.violations(paper, (7,))[:, 0, 0].tolist() == [False, False, True]
    # limits are wrapped offsets from the reference: a DOF near +-pi is measured across the seam
    lim_pi = JointLimits((7,), np.full((1, 3), np.pi), np.full((1, 3), -0.1), np.full((1, 3), 0.1))
    x = np.array([[[np.pi - 0.05, -np.pi + 0.05, np.pi - 0.2]]]).reshape(1, 1, 3)
    assert lim_pi.violations(x, (7,)).tolist() == [[[False, False, True]]]


def test_stylize_kernel_with_bands_vs_reference():
    """The banded kernel against a loop: one factor per DOF, min over the two sides."""
    from convsynth_jax.walktalk.splice import JointLimits, LoopStats, stylize_bands

    rng = np.random.default_rng(3)
    ge = rng.normal(0, 1.0, (17, 4, 3))
    b_l, sd, b_g = rng.normal(0, 0.3, (4, 3)), rng.uniform(0.05, 0.6, (4, 3)), rng.normal(0, 0.3, (4, 3))
    lim = JointLimits(tuple(range(4)), np.zeros((4, 3)), rng.uniform(-1.5, -0.4, (4, 3)), rng.uniform(0.4, 1.5, (4, 3)))
    got = stylize(ge, LoopStats(b_l, sd), b_g, 3.0, lim, tuple(range(4)))
    down, up = stylize_bands(LoopStats(b_l, sd), 3.0, lim, tuple(range(4)))
    for a in range(4):
        for d in range(3):
            dev = ge[:, a, d] - b_g[a, d]
            s = 1.0
            if -dev.min() > down[a, d]:
                s = min(s, down[a, d] / -dev.min())
            if dev.max() > up[a, d]:
                s = min(s, up[a, d] / dev.max())
            np.testing.assert_allclose(got[:, a, d], b_l[a, d] + s * dev, atol=1e-5)
    loose = JointLimits(lim.joints, lim.ref, lim.lo - 1e-5, lim.hi + 1e-5)
    assert not loose.violations(got, tuple(range(4))).any()
    assert np.all(np.abs(got - b_l) <= 3.0 * sd + 1e-5)


def test_bounce_reserve_stays_in_band_without_rescaling_the_gesture(loop):
    """splice.bounce_fit=reserve (ours): the stylization leaves the bounce's room free in the
    elbow DOF's band, so the spliced elbow is the stylized one plus exactly k dH_root and still
    inside B_L +- c sigma, with or without the range-of-motion cut; a band too narrow for the
    bounce (c = 0.3 here: +-2 deg against a +-10 deg bounce) takes it scaled down. The old order
    (bounce added, then rescaled once more when limits were given; added unchecked otherwise)
    broke one or the other."""
    from convsynth_jax.walktalk.splice import JointLimits, bounce_offsets

    body = find_body(loop.motion.skeleton)
    lc = loop_context(loop, body)
    gc = gesture_context(make_gesture(synthetic_gesture(), GaitParams(), PhaseParams()), body)
    k = 2.0
    wide = JointLimits(lc.joints, np.zeros_like(lc.stats.mean), np.full_like(lc.stats.mean, -10.0),
                       np.full_like(lc.stats.mean, 10.0))
    always = np.ones(200, bool)
    loco = tile_loop(loop, 200)
    idx = [lc.joints.index(j) for j in gc.joints]
    elbow = gc.joints.index(body.joints["elbow_r"])
    dof = lc.elbow_dof["r"]
    gains = {}
    for c, limits in itertools.product((3.0, 0.3), (None, wide)):
        p = SpliceParams(k_bounce=k, c=c)
        r = splice_gesture(lc, gc, 3.0, 200, p, "stylized+synced", loco=loco, contact=always, limits=limits)
        d_b = bounce_offsets(loop.root_height, k, r.offset, gc.gesture.motion.num_frames)
        diff = r.arm_euler[:, elbow, dof] - r.styled_euler[:, elbow, dof]
        gain = float(np.dot(diff, d_b) / np.dot(d_b, d_b))
        np.testing.assert_allclose(diff, gain * d_b, atol=1e-9)   # the bounce's shape, unrescaled gesture
        band = c * lc.stats.std[idx]
        assert np.all(np.abs(r.arm_euler - lc.stats.mean[idx]) <= band + 1e-5)
        gains[c] = gain
    assert gains[3.0] == pytest.approx(1.0)          # room enough: R' = R + k dH exactly
    assert 0.0 < gains[0.3] < 1.0                    # a band narrower than the bounce: scaled to fit
    assert np.ptp(loop.root_height) * np.radians(k) > 0.3 * 2 * lc.stats.std[idx][elbow, dof]


def test_soft_joint_limit_planted():
    """joint_limit_mode=soft (ours): the band side is a smooth, strictly growing function of the
    paper's c sigma that never passes the range of motion and never exceeds the hard cut. Planted:
    room 1.0 rad, width 0.1: a band far inside keeps its size (within 0.1 * log(1 + e^-9)), a band
    at the limit is cut by 0.1 * log 2, one far past it tends to the limit; two bands past the
    limit that the hard cut makes equal stay ordered (the stroke still follows the loop)."""
    from convsynth_jax.walktalk.splice import JointLimits, LoopStats, soft_cap, stylize_bands

    band = np.array([0.1, 1.0, 1.5, 3.0, 10.0])
    got = soft_cap(band, 1.0, 0.1)
    np.testing.assert_allclose(got[0], 0.1 - 0.1 * np.log1p(np.exp(-9.0)), atol=1e-6)
    np.testing.assert_allclose(got[1], 1.0 - 0.1 * np.log(2.0))
    np.testing.assert_allclose(got[-1], 1.0, atol=1e-12)
    assert np.all(got <= np.minimum(band, 1.0)) and np.all(np.diff(got) > 0)
    assert got[3] < got[4] and np.minimum(band, 1.0)[3] == np.minimum(band, 1.0)[4]
    assert soft_cap(0.0, 0.05, 0.1) == 0.0   # floored at 0, never a negative band
    # through stylize_bands: B_L 2, std 1, c 3 (paper 3 each side), limits ref 2, lo -1.5, hi 10
    stats = LoopStats(np.full((1, 3), 2.0), np.ones((1, 3)))
    lim = JointLimits((7,), np.full((1, 3), 2.0), np.full((1, 3), -1.5), np.full((1, 3), 10.0))
    hard = stylize_bands(stats, 3.0, lim, (7,))
    soft = stylize_bands(stats, 3.0, lim, (7,), mode="soft", softness_deg=np.degrees(0.1))
    np.testing.assert_allclose(hard[0], 1.5)
    np.testing.assert_allclose(soft[0], soft_cap(3.0, 1.5, 0.1))
    np.testing.assert_allclose(soft[1], soft_cap(3.0, 10.0, 0.1))
    with pytest.raises(WalkTalkError, match="joint_limit_mode"):
        SpliceParams(joint_limit_mode="clip")
    with pytest.raises(WalkTalkError, match="softness"):
        SpliceParams(joint_limit_softness_deg=0.0)
    with pytest.raises(WalkTalkError, match="band_std"):
        SpliceParams(band_std="gait")


def test_gait_min_band_moves_the_stroke_by_the_base_pose_only():
    """band_std=gait_min (ours). Planted: two jog loops, elbows at 60 and 70 deg mean, swinging
    +-10 and +-5 deg. With the paper's band (each loop's own std) the raised arm's stroke lands on
    B_L + c sigma_L of its loop, so the elbow's excursion past B_L differs by the ratio of the
    stds (2x); with the gait's smallest std both loops get the same excursion and the stroke
    differs by B_L's difference alone, still within each loop's own +- c sigma."""
    from convsynth_jax.walktalk.pipeline import share_gait_band

    loops = [extract_loop(synthetic_jog(periods=3.5, elbow_mean_deg=m, elbow_amp_deg=a)[0], GaitParams())
             for m, a in ((60.0, 10.0), (70.0, 5.0))]
    body = find_body(loops[0].motion.skeleton)
    lcs = share_gait_band([loop_context(lp, body) for lp in loops])
    np.testing.assert_allclose(lcs[0].gait_min_std, np.minimum(lcs[0].stats.std, lcs[1].stats.std))
    gc = gesture_context(make_gesture(synthetic_gesture(), GaitParams(), PhaseParams()), body)
    idx = [lcs[0].joints.index(j) for j in gc.joints]
    elbow = gc.joints.index(body.joints["elbow_r"])
    dof = lcs[0].elbow_dof["r"]
    # the planted gesture lifts the upper arm only: give its forearm a flexion the band must rescale
    ge = gc.euler.copy()
    prof = np.sin(np.linspace(0, np.pi, len(ge))) ** 2
    ge[:, elbow, dof] = gc.rest[elbow, dof] + np.radians(80.0) * prof
    gc = dataclasses.replace(gc, euler=ge)
    exc = {}
    for band in ("loop", "gait_min"):
        p = SpliceParams(band_std=band)
        for i, lc in enumerate(lcs):
            r = splice_gesture(lc, gc, 3.0, 200, p, "stylized")
            dev = r.styled_euler[:, elbow, dof] - lc.stats.mean[idx][elbow, dof]
            exc[band, i] = float(np.max(np.abs(dev)))
            assert np.all(np.abs(r.styled_euler - lc.stats.mean[idx]) <= 3.0 * lc.stats.std[idx] + 1e-5)
    sd = [lc.stats.std[idx][elbow, dof] for lc in lcs]
    assert sd[0] > 1.5 * sd[1]
    np.testing.assert_allclose(exc["loop", 0] / exc["loop", 1], sd[0] / sd[1], rtol=1e-4)
    np.testing.assert_allclose(exc["gait_min", 0], exc["gait_min", 1], rtol=1e-4)
    np.testing.assert_allclose(exc["gait_min", 0], 3.0 * sd[1], rtol=1e-4)
    # a loop alone (no gait set shared) keeps its own band
    solo = loop_context(loops[0], body)
    r = splice_gesture(solo, gc, 3.0, 200, SpliceParams(band_std="gait_min"), "stylized")
    np.testing.assert_allclose(np.max(np.abs(r.styled_euler[:, elbow, dof] - solo.stats.mean[idx][elbow, dof])),
                               3.0 * sd[0], rtol=1e-4)


def test_splice_arrays_window_equals_full_timeline_kernel():
    """splice_arrays runs the kernel only over the frames where w > 0 (speed, ours): bit for bit
    the kernel over the whole timeline, including the frames outside (the locomotion in float32);
    no frame with w > 0 also works (the locomotion)."""
    from convsynth_jax.walktalk.splice import splice_kernel

    rng = np.random.default_rng(7)
    T, J = 90, 5
    lq = Rotation.random(T * J, random_state=8).as_quat().reshape(T, J, 4)
    gq = Rotation.random(T * J, random_state=9).as_quat().reshape(T, J, 4)
    w = np.zeros(T)
    w[30:61] = rng.uniform(0.01, 1, 31)
    w[40:50] = 1.0
    arm = np.array([True, False, True, True, False])
    full = np.asarray(splice_kernel(lq.astype(np.float32), gq.astype(np.float32), w.astype(np.float32), arm))
    np.testing.assert_array_equal(splice_arrays(lq, gq, w, arm), full)
    np.testing.assert_array_equal(splice_arrays(lq, gq, np.zeros(T), arm), lq.astype(np.float32))


def _seam_slide_ref(motion, n_loop, p, body, pos, window=5):
    """The obvious loop (the former seam_foot_slide) the vectorized one is checked against."""
    from convsynth_jax.walktalk.locomotion import _horizontal_speed, foot_down

    worst = 0.0
    for side in ("l", "r"):
        for key in (f"foot_{side}", f"toes_{side}"):
            x = pos[:, body.joints[key]]
            down = foot_down(x[:, 1], _horizontal_speed(x, motion.fps), p)
            for s in range(n_loop, motion.num_frames, n_loop):
                for t in range(max(1, s - window), min(motion.num_frames, s + window + 1)):
                    if down[t - 1] and down[t]:
                        worst = max(worst, float(np.linalg.norm(x[t, [0, 2]] - x[t - 1, [0, 2]])))
    return worst


def test_seam_foot_slide_vectorized_vs_loop(jog):
    from convsynth_jax.walktalk.locomotion import seam_foot_slide

    m = jog[0]
    body = find_body(m.skeleton)
    pos = forward_kinematics_np(m)
    rng = np.random.default_rng(1)
    for n_loop in (7, 20, 31, 200):
        noisy = pos + rng.normal(0, 0.3, pos.shape)   # slides of different sizes near every seam
        for window in (1, 5):
            assert seam_foot_slide(m, n_loop, GaitParams(), body, noisy, window) == pytest.approx(
                _seam_slide_ref(m, n_loop, GaitParams(), body, noisy, window), abs=1e-12)
    assert seam_foot_slide(m, 10_000, GaitParams(), body, pos) == 0.0


def test_rescale_coupling_joint_planted():
    """rescale_coupling=1, one factor per joint (ours): one factor per joint, the smallest of its DOFs' factors.
    Planted: joint 0 deviates by 10, 2 and -0.5 (std 1, c 3: per-DOF factors 0.3, 1, 1), joint 1
    stays inside its band (factor 1). The paper's per-DOF rule rescales only joint 0's first
    channel; the joint rule scales all three of joint 0 by 0.3 and leaves joint 1 alone."""
    from convsynth_jax.walktalk.splice import JointLimits, LoopStats, stylize_bands

    ge = np.zeros((3, 2, 3))
    ge[:, 0] = np.outer([0.0, 0.5, 1.0], [10.0, 2.0, -0.5])
    ge[:, 1] = np.outer([0.0, 0.5, 1.0], [1.0, -2.0, 0.5])
    st = LoopStats(np.full((2, 3), 2.0), np.ones((2, 3)))
    dof = stylize(ge, st, np.zeros((2, 3)), 3.0)
    joint = stylize(ge, st, np.zeros((2, 3)), 3.0, coupling=1.0)
    np.testing.assert_allclose(dof[:, 0], 2.0 + ge[:, 0] * [0.3, 1.0, 1.0], atol=1e-6)
    np.testing.assert_allclose(joint[:, 0], 2.0 + 0.3 * ge[:, 0], atol=1e-6)
    np.testing.assert_allclose(joint[:, 1], 2.0 + ge[:, 1], atol=1e-6)
    np.testing.assert_allclose(dof[:, 1], joint[:, 1], atol=1e-6)
    # with random bands and limits: the joint's factor is the min of the per-DOF reference factors,
    # and every DOF stays in its band and limits
    rng = np.random.default_rng(5)
    ge = rng.normal(0, 1.0, (19, 4, 3))
    b_l, sd, b_g = rng.normal(0, 0.3, (4, 3)), rng.uniform(0.05, 0.6, (4, 3)), rng.normal(0, 0.3, (4, 3))
    lim = JointLimits(tuple(range(4)), np.zeros((4, 3)), rng.uniform(-1.5, -0.4, (4, 3)), rng.uniform(0.4, 1.5, (4, 3)))
    got = stylize(ge, LoopStats(b_l, sd), b_g, 3.0, lim, tuple(range(4)), coupling=1.0)
    down, up = stylize_bands(LoopStats(b_l, sd), 3.0, lim, tuple(range(4)))
    dev = ge - b_g
    s = np.ones((4, 3))
    s = np.where(-dev.min(0) > down, down / -dev.min(0), s)
    s = np.minimum(s, np.where(dev.max(0) > up, up / dev.max(0), 1.0))
    np.testing.assert_allclose(got, b_l + dev * s.min(axis=1, keepdims=True), atol=1e-5)
    assert np.all(got - b_l >= -down - 1e-5) and np.all(got - b_l <= up + 1e-5)
    with pytest.raises(WalkTalkError, match="rescale_coupling"):
        SpliceParams(rescale_coupling=1.5)
    with pytest.raises(WalkTalkError, match="rescale coupling"):
        stylize(ge, LoopStats(b_l, sd), b_g, 3.0, coupling=-0.1)


def test_rescale_coupling_through_the_pipeline(loop):
    """Through splice_gesture (stylized+synced, bounce reserve): with rescale_coupling=1 each
    gesturing joint's stylized deviation from B_L is one factor times its offset deviation
    (M_G + B_D - B_L), that factor the smallest of the joint's per-DOF factors under the paper's
    rule, and every DOF stays within the loop's +- c sigma."""
    body = find_body(loop.motion.skeleton)
    lc = loop_context(loop, body)
    gc = gesture_context(make_gesture(synthetic_gesture(), GaitParams(), PhaseParams()), body)
    idx = [lc.joints.index(j) for j in gc.joints]
    ge = gc.euler.copy()   # give the forearm a flexion and the upper arm a second moving channel
    prof = np.sin(np.linspace(0, np.pi, len(ge))) ** 2
    elbow, upper = gc.joints.index(body.joints["elbow_r"]), gc.joints.index(body.joints["upperarm_r"])
    ge[:, elbow, lc.elbow_dof["r"]] += np.radians(80.0) * prof
    ge[:, upper, lc.elbow_dof["r"]] += np.radians(60.0) * prof   # (its channel 0 has a zero band)
    gc = dataclasses.replace(gc, euler=ge)
    b_l, sd = lc.stats.mean[idx], lc.stats.std[idx]
    off = ge + (b_l - gc.rest) - b_l
    rng_off = off.max(0) - off.min(0)
    big = rng_off > 1e-6            # DOFs the gesture moves (the others have no factor to measure)
    facs = {}
    for group, g in (("dof", 0.0), ("joint", 1.0), ("half", 0.5)):
        r = splice_gesture(lc, gc, 3.0, 200, SpliceParams(rescale_coupling=g), "stylized+synced")
        dev = r.styled_euler - b_l
        assert np.all(np.abs(dev) <= 3.0 * sd + 1e-5)
        f = np.full((len(idx), 3), np.nan)
        f[big] = (dev.max(0) - dev.min(0))[big] / rng_off[big]
        facs[group] = f
        np.testing.assert_allclose(dev, off * np.nan_to_num(f, nan=1.0), atol=1e-5)   # one factor per DOF
    d, j = facs["dof"], facs["joint"]
    assert np.nanmax(d[elbow]) - np.nanmin(d[elbow]) > 0.1 or np.nanmax(d[upper]) - np.nanmin(d[upper]) > 0.1
    for a in range(len(idx)):   # the paper's factors differ within a joint; the joint rule takes their min
        if big[a].any():
            np.testing.assert_allclose(j[a][big[a]], np.nanmin(d[a]), atol=1e-4)
            np.testing.assert_allclose(facs["half"][a][big[a]], np.sqrt(d[a][big[a]] * np.nanmin(d[a])), atol=1e-4)
