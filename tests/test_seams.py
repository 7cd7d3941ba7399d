"""The seam edge filter (graph/seams.py, ours) and the finger weight of the transition cost
(features.finger_weight, ours): slow references and a planted fast finger stroke at a transition."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from convsynth_jax.data.skeleton_seated import seated_skeleton
from convsynth_jax.evaluation.metrics import seam_ratio
from convsynth_jax.graph import build_database, build_graph
from convsynth_jax.graph.params import FeatureParams, GraphParams
from convsynth_jax.graph.seams import frame_acceleration, near_fast_frames, seam_filter_mask
from convsynth_jax.kinematics import forward_kinematics
from convsynth_jax.skeleton import Motion
from convsynth_jax.synth.realize import realize
from test_realize import _with_glitch  # one planted marker swap for the glitch tests

N = 150
FLICK = 75  # clip "b": the left wrist flicks here (moves only the finger joints, weight 0 in Eq. 4)


def _clip(skel, name, phase, flick=0.0):
    """Slow arm and spine sway (one sinusoid, so poses recur across clips at other phases); with
    ``flick`` a 4-frame wrist snap of that many degrees at FLICK."""
    J = skel.num_joints
    t = np.arange(N) / 30.0
    ang = np.zeros((N, J, 3))
    s = np.sin(2 * np.pi * 0.4 * t + phase)
    for name_j, axis, amp in (("Spine1", 0, 0.08), ("LeftArm", 2, 0.3), ("RightArm", 2, -0.3),
                              ("LeftForeArm", 1, 0.25), ("RightForeArm", 1, -0.25), ("Head", 1, 0.15)):
        ang[:, skel.names.index(name_j), axis] = amp * s
    if flick:
        ang[FLICK:FLICK + 4, skel.names.index("LeftHand"), 0] = np.deg2rad(flick * np.array([0.5, 1.0, 1.0, 0.5]))
    q = Rotation.from_rotvec(ang.reshape(-1, 3)).as_quat()[:, [3, 0, 1, 2]].reshape(N, J, 4)
    tr = np.broadcast_to(skel.offsets, (N, J, 3)).copy()
    tr[:, 0] = [0.0, 90.0, 0.0]
    return Motion(skel, q, tr, 30.0, name)


@pytest.fixture(scope="module")
def planted():
    skel = seated_skeleton()
    motions = {"a": _clip(skel, "a", 0.0), "b": _clip(skel, "b", 2.0, flick=50.0), "c": _clip(skel, "c", 4.0)}
    return motions, build_database([(k, m, None, None) for k, m in motions.items()])


def _slow_acceleration(db):
    """The obvious loop: every frame, every joint, the central second difference in its clip."""
    out = np.zeros(db.num_frames)
    for n in range(db.num_frames):
        lo, hi = n - 1, n + 1
        s, e = db.offsets[db.clip[n]], db.offsets[db.clip[n] + 1]
        if lo < s:
            lo, n_c, hi = n, n + 1, n + 2
        elif hi >= e:
            lo, n_c, hi = n - 2, n - 1, n
        else:
            n_c = n
        best = 0.0
        for b in range(db.positions.shape[1]):
            d = (db.positions[hi, b].astype(np.float64) - 2 * db.positions[n_c, b] + db.positions[lo, b]) * db.fps ** 2
            best = max(best, float(np.sqrt((d * d).sum())))
        out[n] = best
    return out


def _slow_near(db, acc, limit, radius):
    out = np.zeros(db.num_frames, bool)
    for n in range(db.num_frames):
        for m in range(db.num_frames):
            if db.clip[m] == db.clip[n] and abs(m - n) <= radius and acc[m] > limit:
                out[n] = True
    return out


def test_frame_acceleration_and_fast_neighbourhood_equal_the_loops(planted):
    _, db = planted
    acc = frame_acceleration(db)
    np.testing.assert_allclose(acc, _slow_acceleration(db), rtol=1e-6, atol=1e-6)
    b0 = int(db.offsets[1])
    assert int(np.argmax(acc)) in range(b0 + FLICK - 1, b0 + FLICK + 5)  # the planted flick is the fastest
    limit = float(np.quantile(acc, 0.95))
    for r in (0, 1, 4):
        np.testing.assert_array_equal(near_fast_frames(db, acc, limit, r), _slow_near(db, acc, limit, r))


def _realized_seam(motions, g, e, gt):
    """Seam ratio of a 50-frame path: 25 frames of the edge's source clip up to its source frame,
    then 25 of its target clip from the target frame (blend and metric as in leave-one-out). None
    where the source clip ends inside the blend (its continuation would be clamped)."""
    sc, sf, tc, tf = e
    if sf < 24 or sf + 13 >= N or tf + 25 > N:
        return None
    clips = [sc] * 25 + [tc] * 25
    frames = list(range(sf - 24, sf + 1)) + list(range(tf, tf + 25))
    m = realize(clips, frames, motions, [25], blend_frames=12)
    return seam_ratio(np.asarray(forward_kinematics(m)), np.asarray(forward_kinematics(gt)), 30.0, [25])


def _synthetic_edges(g):
    ef = g.edges_frame()
    syn = ef[ef["synthetic"]] if "synthetic" in ef else ef
    return [tuple(r) for r in syn[["source_file", "source_frame", "target_file", "target_frame"]].itertuples(index=False)]


def test_planted_finger_stroke_at_a_transition(planted):
    """Fingers weigh 0 in the cost, so the paper's graph admits transitions right at the 50-degree
    wrist flick of clip b, and a path through one has a seam sharper than the held-out ground truth
    (the same sway with one 15-degree wrist beat): a seam_ratio > 1. With the seam filter no transition starts or lands within its radius of the
    flick, every remaining transition's seam is <= 1, and the graph keeps most of its states."""
    motions, db = planted
    # the flick turns the wrist 25 degrees a frame: the glitch filter (preset=quality) would drop its
    # transitions too, so both graphs here leave it off to show the seam filter alone
    base = GraphParams(key_fraction=1.0, use_audio_keys=False)
    old = build_graph(db, base)
    new = build_graph(db, GraphParams(key_fraction=1.0, use_audio_keys=False, seam_filter_quantile=0.95,
                                      glitch_max_step_deg=0.0))

    def near_flick(e):  # within 3 frames of the flick's frames FLICK .. FLICK + 3
        return any(c == "b" and FLICK - 3 <= f <= FLICK + 6 for c, f in ((e[0], e[1]), (e[2], e[3])))

    old_e, new_e = _synthetic_edges(old), _synthetic_edges(new)
    assert any(near_flick(e) for e in old_e)
    assert not any(near_flick(e) for e in new_e)
    assert new.meta["kernel"]["seam_filter"]["dropped"] > 0
    assert new.num_states >= 0.8 * old.num_states and len(new_e) > 0
    gt = _clip(seated_skeleton(), "held_out", 1.0, flick=15.0)
    old_r = [r for e in old_e if near_flick(e) and (r := _realized_seam(motions, old, e, gt)) is not None]
    assert max(old_r) > 1.0, max(old_r)
    rng = np.random.default_rng(0)
    sample = [new_e[k] for k in rng.choice(len(new_e), min(60, len(new_e)), replace=False)]
    new_r = [r for e in sample if (r := _realized_seam(motions, new, e, gt)) is not None]
    assert new_r and max(new_r) <= 1.0, max(new_r)


def test_seam_filter_mask_on_a_planted_fast_frame(planted):
    _, db = planted
    acc = np.zeros(db.num_frames)
    acc[10] = 5.0  # clip a, frame 10
    a = np.array([10, 14, 15, 200, 160])
    j = np.array([300, 300, 300, 7, 12])  # database indices: clip a is 0-149, b 150-299, c 300-449
    keep, limit = seam_filter_mask(db, a, j, 0.99, 4, acc=acc)
    assert limit == 0.0
    np.testing.assert_array_equal(keep, [False, False, True, False, False])


def test_finger_weight_reaches_the_cost():
    """features.finger_weight (ours): 0 by default (the paper), else the finger joints' w_b."""
    skel = seated_skeleton()
    fingers = [k for k, n in enumerate(skel.names) if "Thumb" in n or "Index" in n or "Middle" in n]
    clips = [("a", _clip(skel, "a", 0.0), None, None)]
    w0 = build_database(clips).weights
    w5 = build_database(clips, FeatureParams(finger_weight=0.5)).weights
    assert np.all(w0[fingers] == 0) and np.all(w5[fingers] == 0.5)
    others = np.setdiff1d(np.arange(skel.num_joints), fingers)
    assert np.all(w0[others] == 1) and np.all(w5[others] == 1)
    # a pose that differs from another only by the wrist flick (which moves the finger joints alone)
    # costs nothing with the paper's weights and something with finger_weight > 0 (Eq. 4)
    from convsynth_jax.graph.cost import aligned_distance

    flick = [("b", _clip(skel, "b", 0.0, flick=50.0), None, None)]
    for fp, want_zero in ((FeatureParams(), True), (FeatureParams(finger_weight=0.5), False)):
        da, db_ = build_database(clips, fp), build_database(flick, fp)
        d = np.asarray(aligned_distance(da.positions[FLICK + 1:FLICK + 2], da.velocities[FLICK + 1:FLICK + 2],
                                        db_.positions[FLICK + 1:FLICK + 2], db_.velocities[FLICK + 1:FLICK + 2],
                                        da.weights.astype(np.float32), 1.0))
        assert (abs(d[0]) < 1e-4) == want_zero, d


@pytest.mark.parametrize("override, key", [("graph.seam_filter_quantile=1.5", "graph.seam_filter_quantile"),
                                           ("graph.seam_filter_quantile=0", "graph.seam_filter_quantile"),
                                           ("graph.seam_filter_radius=-1", "graph.seam_filter_radius"),
                                           ("features.finger_weight=-0.5", "features.finger_weight")])
def test_bad_seam_options_are_config_errors_naming_the_key(override, key):
    # np.quantile raised a bare ValueError for 1.5; a negative radius or finger weight passed silently
    from convsynth_jax.config import default_params
    from convsynth_jax.errors import ConfigError

    with pytest.raises(ConfigError, match=key):
        default_params([override])


def test_glitch_filter_drops_transitions_next_to_a_planted_marker_swap():
    """Clip b has a 29-degree right-arm glitch at frames 40-41 (steps into 40 and into 42).
    Synthetic transitions whose source or destination lies within 4 frames of those steps' frames
    (35..46 of b) are dropped, the others kept; the joint turn the database stores is the slow one."""
    from convsynth_jax.graph.seams import apply_glitch_filter, glitch_filter_mask

    skel = seated_skeleton()
    motions = {"a": _clip(skel, "a", 0.0), "b": _with_glitch(_clip(skel, "b", 2.0), "RightArm", [40, 41], 29.0)}
    db = build_database([(k, m, None, None) for k, m in motions.items()])
    # the stored turn against a loop over frames and joints
    slow = np.zeros(db.num_frames)
    for n in range(db.num_frames):
        if db.frame[n] == 0:
            continue
        for b in range(1, skel.num_joints):
            d = abs(float(np.dot(db_rot(motions, db, n, b), db_rot(motions, db, n - 1, b))))
            slow[n] = max(slow[n], np.rad2deg(2 * np.arccos(min(1.0, d))))
    np.testing.assert_allclose(db.joint_turn, slow, atol=1e-3)
    assert db.joint_turn[N + 40] > 25 and db.joint_turn[N + 42] > 25 and db.joint_turn[:N].max() < 5
    a = np.array([10, N + 34, N + 35, N + 46, N + 47, 20])
    j = np.array([N + 10, 5, 5, 5, 5, N + 36])
    np.testing.assert_array_equal(glitch_filter_mask(db, a, j, 15.0, 4), [True, True, False, False, True, False])
    c = np.arange(a.size, dtype=np.float32)
    kept = apply_glitch_filter(db, a, j, c, GraphParams(glitch_max_step_deg=15.0), meta=(meta := {}))
    np.testing.assert_array_equal(kept[2], [0, 1, 4])
    assert meta["glitch_filter"]["dropped"] == 3
    off = apply_glitch_filter(db, a, j, c, GraphParams(glitch_max_step_deg=0.0))
    np.testing.assert_array_equal(off[2], c)


def db_rot(motions, db, n, b):
    return np.asarray(motions[db.clip_names[db.clip[n]]].rotations[db.frame[n], b], np.float64)


def test_glitch_filter_leaves_no_synthetic_transition_next_to_the_glitch_in_a_built_graph():
    """Built graphs: without the filter some synthetic transitions leave or enter clip b within 4 frames
    of its glitch's steps (frames 35..46); with it (preset=quality's 15 degrees) none does."""
    skel = seated_skeleton()
    motions = {"a": _clip(skel, "a", 0.0), "b": _with_glitch(_clip(skel, "b", 2.0), "RightArm", [40, 41], 29.0),
               "c": _clip(skel, "c", 4.0)}
    db = build_database([(k, m, None, None) for k, m in motions.items()])

    def touching(**p):
        g = build_graph(db, GraphParams(seed=0, **p))
        near = (np.asarray(g.clip_names)[g.clip] == "b") & (g.frame >= 35) & (g.frame <= 46)
        n = 0
        for s in range(g.num_states):
            tg, _, sy = g.out_edges(s)
            n += int(sum(bool(near[s] or near[t]) for t, y in zip(tg, sy) if y))
        return n

    assert touching(glitch_max_step_deg=0.0) > 0
    assert touching(glitch_max_step_deg=15.0) == 0
    assert touching() > 0   # the paper's default: off


def test_glitch_options_are_off_in_the_paper_preset_and_on_in_quality():
    """The glitch filter and the continuation hold are ours: preset=paper (the default) leaves them
    off, preset=quality turns both on."""
    from convsynth_jax.config import default_params

    paper, quality = default_params([]), default_params(["preset=quality"])
    assert paper.graph.glitch_max_step_deg == 0.0 and paper.synth.continuation_max_step_deg == 0.0
    assert quality.graph.glitch_max_step_deg == 15.0 and quality.synth.continuation_max_step_deg == 15.0


def test_the_seam_filter_and_the_seam_metrics_read_one_acceleration(planted):
    """The graph's fast frames and the evaluation's seam metrics are one definition
    (kinematics.seam_acceleration): on the database's positions they agree frame for frame."""
    from convsynth_jax.evaluation.metrics import clip_acceleration, root_relative_acceleration

    _, db = planted
    acc = frame_acceleration(db)
    for s, e in zip(db.offsets[:-1], db.offsets[1:]):
        clip = np.asarray(db.positions[int(s):int(e)], np.float64)
        np.testing.assert_allclose(acc[int(s):int(e)], clip_acceleration(clip, db.fps).max(-1), rtol=1e-12)
        np.testing.assert_allclose(acc[int(s) + 1:int(e) - 1], root_relative_acceleration(clip, db.fps).max(-1), rtol=1e-12)
