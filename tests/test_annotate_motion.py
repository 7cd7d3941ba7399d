"""Motion segmentation: Eq. 1-2 and Figure 3 by hand, joint speeds against a slow NumPy/SciPy forward
kinematics, invariances, real bandai2 clips, and planted events of the tiny synthetic corpus."""
import numpy as np
import pandas as pd
import pytest
from scipy.spatial.transform import Rotation

from convsynth_jax.annotate.motion import (FrameWindow, candidate_windows, detect_in_window, idle_threshold, joint_speeds,
                                           segment_motion, segment_windows)
from convsynth_jax.data.skeleton_seated import INDEX, seated_skeleton
from convsynth_jax.annotate.params import AnnotateParams
from convsynth_jax.errors import ConfigError
from convsynth_jax.rig import find_joints
from convsynth_jax.skeleton import Motion

AP = AnnotateParams()


# ----------------------------------------------------------------------------------- Eq. 1 and Eq. 2
def test_eq1_idle_threshold_by_hand():
    v = np.array([2.0, 4.0, 12.0, 22.0, 2.0])
    assert idle_threshold(v, 0.1) == pytest.approx(2.0 + 0.1 * (22.0 - 2.0))  # 4.0
    assert idle_threshold(v, 0.0) == 2.0 and idle_threshold(v, 1.0) == 22.0
    assert idle_threshold(v, 0.25) == pytest.approx(7.0)
    assert np.isnan(idle_threshold(np.zeros(0), 0.1))


def test_eq2_window_threshold_start_peak_end_by_hand():
    v = np.array([2.0, 4.0, 12.0, 22.0, 2.0, 30.0, 1.0])
    # window frames 1..4: theta_W = 2 + 0.1 * (22 - 2) = 4.0 -> frames 2, 3 above; peak at 3
    assert detect_in_window(v, FrameWindow(1, 5), theta_s=5.0) == (2, 3, 4)
    # frames 0..1 never exceed the clip threshold theta_S = 5 -> no movement
    assert detect_in_window(v, FrameWindow(0, 2), theta_s=5.0) is None
    # alpha_W = 0.5 over frames 1..4: 2 + 0.5 * 20 = 12 -> only frame 3 is above (12 is not > 12)
    assert detect_in_window(v, FrameWindow(1, 5), theta_s=5.0, alpha_w=0.5) == (3, 3, 4)
    assert detect_in_window(v, FrameWindow(3, 3), theta_s=0.0) is None  # empty window


# --------------------------------------------------------------------------------------- Figure 3
def test_figure3_windows_expand_and_trim_at_audio_neighbours():
    seg = pd.DataFrame({"start": [1.0, 2.2, 5.0, 29.5], "end": [2.0, 3.0, 5.5, 29.9]})
    w = candidate_windows(seg, num_frames=300, fps=10)
    assert w[0] == FrameWindow(5, 22)    # [0.5, 2.5] -> next segment starts at 2.2
    assert w[1] == FrameWindow(20, 34)   # [1.8, 3.4] -> previous segment ends at 2.0
    assert w[2] == FrameWindow(47, 58)   # [4.75, 5.75], nothing in reach (floor/ceil to frames)
    assert w[3] == FrameWindow(293, 300)  # [29.3, 30.1] clipped to the clip's 300 frames
    # neighbours from another table (e.g. all segments of the channel while windows are for PCs only)
    w = candidate_windows(seg.iloc[[2]], 300, 10, neighbours=pd.DataFrame({"start": [4.9], "end": [5.1]}))
    assert w == [FrameWindow(47, 58)]    # an overlapping neighbour is neither before nor after: no trimming


def test_figure3_windows_trim_at_motion_segments():
    seg = pd.DataFrame({"start": [10.0], "end": [12.0]})  # expanded: [9, 13], centre 11
    motion = pd.DataFrame({"start": [8.0, 12.5, 20.0], "end": [9.6, 14.0, 21.0]})
    assert candidate_windows(seg, 1000, 10, motion_segments=motion) == [FrameWindow(96, 125)]
    assert candidate_windows(seg, 1000, 10) == [FrameWindow(90, 130)]


def test_segment_windows_trims_against_the_previous_movement():
    v = np.zeros(40)
    v[5:15] = [1, 3, 6, 9, 10, 9, 6, 3, 2, 0]   # a movement over frames 5..13
    v[25:30] = [2, 6, 8, 6, 2]
    # theta_S = 0 + 0.1 * 10 = 1; window [0, 20): theta_W = 1 -> frames 6..13 are above (1 is not)
    # second window [10, 30) overlaps the first movement: it restarts at frame 14, where the first
    # movement ended; theta_W = 0.8 there -> frames 25..29
    found = segment_windows(v, [FrameWindow(0, 20), FrameWindow(10, 30)], theta_s=idle_threshold(v, 0.1), alpha_w=0.1)
    assert found[0] == (6, 9, 14)
    assert found[1] == (25, 27, 30)
    untrimmed = segment_windows(v, [FrameWindow(0, 20), FrameWindow(10, 30)], idle_threshold(v, 0.1), 0.1, trim_motion=False)
    assert untrimmed[1][0] == 10  # would start inside the earlier movement


def test_trimming_uses_the_full_extent_of_a_movement_that_outlasts_its_window():
    v = np.zeros(40)
    v[5:18] = [2, 5, 8, 10, 8, 6, 5, 4, 3, 3, 2, 2, 0.5]  # a gesture outlasting its window [0, 12)
    v[25:30] = [2, 6, 8, 6, 2]                             # the next clause's own gesture
    wins = [FrameWindow(0, 12), FrameWindow(12, 30)]
    theta_s = idle_threshold(v, 0.1)  # 1.0
    # window 1: theta_W = 1 -> frames 5..11, end cut at the window's end (frame 12)
    # paper-literal: window 2 [12, 30) starts with the tail (4, 3, 3, 2, 2 > theta_W 0.8) -> counted again
    assert segment_windows(v, wins, theta_s, 0.1, extend_trim=False) == [(5, 8, 12), (12, 27, 30)]
    # extended: the first movement occupies frames up to 17, where its speed falls to 0.5 <= 1
    assert segment_windows(v, wins, theta_s, 0.1, extend_trim=True) == [(5, 8, 12), (25, 27, 30)]


def test_segment_motion_events_and_alphas():
    fps = 10.0
    n = 200
    speeds = {k: np.full(n, 0.5) for k in ("LH", "RH", "Nod")}
    speeds["LH"][48:57] = [2, 5, 8, 10, 8, 5, 3, 2, 1]     # around the PC [5.0, 5.6]
    speeds["Nod"][121:126] = [3, 6, 9, 6, 3]                 # around the LR [12.0, 12.4]
    speeds["Nod"][150:155] = [3, 6, 9, 6, 3]                 # around the partner's HP [15.0, 15.4]
    own = pd.DataFrame({"kind": ["PC", "LR"], "start": [5.0, 12.0], "end": [5.6, 12.4]})
    partner = pd.DataFrame({"kind": ["PC", "HP"], "start": [1.0, 15.0], "end": [2.0, 15.4]})
    ev = segment_motion(speeds, own, fps, partner, AP)
    assert ev[["kind", "channel", "segment"]].values.tolist() == [["LH", "own", 0], ["Nod", "own", 1],
                                                                  ["Nod", "partner", 1]]
    # LH window [4.7, 5.9] -> frames 47..58; theta_W = 0.5 + 0.1 * 9.5 = 1.45 -> frames 48..55 above
    np.testing.assert_allclose(ev.loc[0, ["start", "peak", "end"]].astype(float), [4.8, 5.1, 5.6])
    assert list(ev.columns) == ["kind", "start", "peak", "end", "channel", "segment"]
    # with alpha_s = 1 the clip threshold is each curve's maximum, which nothing exceeds
    assert segment_motion(speeds, own, fps, partner, AP, alpha_s=1.0).empty
    assert len(segment_motion(speeds, own, fps, partner, AnnotateParams(alpha_s=1.0))) == 0
    # theta_S is per clip: a fast head movement elsewhere (speed 20 at frame 190) lifts the nod
    # threshold to 0.5 + 0.5 * 19.5 = 10.25 > 9, while LH keeps 0.5 + 0.5 * 9.5 = 5.25 < 10
    speeds["Nod"][190] = 20.0
    assert segment_motion(speeds, own, fps, partner, AP, alpha_s=0.5)["kind"].tolist() == ["LH"]
    assert segment_motion(speeds, own, fps, partner, AP, alpha_s=0.1)["kind"].tolist() == ["LH", "Nod", "Nod"]
    assert segment_motion(speeds, own.iloc[:0], fps, None, AP).empty


# ---------------------------------------------------------------------------------- joint speeds
def _random_motion(rng, n=24, fps=30.0, root_motion=True, spine_motion=True):
    skel = seated_skeleton()
    J = skel.num_joints
    euler = rng.normal(0, 12, (n, J, 3)).cumsum(axis=0) * 0.3
    if not spine_motion:
        euler[:, [INDEX["Spine"], INDEX["Spine1"], INDEX["Spine2"]]] = 0.0
    if not root_motion:
        euler[:, 0] = 0.0
    q = Rotation.from_euler("ZXY", euler.reshape(-1, 3), degrees=True).as_quat()[:, [3, 0, 1, 2]].reshape(n, J, 4)
    trans = np.broadcast_to(skel.offsets, (n, J, 3)).copy()
    trans[:, 0] = rng.normal(0, 3, (n, 3)).cumsum(axis=0) if root_motion else 0.0
    return Motion(skel, q, trans, fps)


def _reference_speeds(motion, hand, shoulder, frame, head, neck, neck_frame, head_end, up=1):
    """Slow forward kinematics with SciPy rotations, frame by frame, joint by joint (float64)."""
    skel = motion.skeleton
    n, J = motion.num_frames, skel.num_joints
    pos = np.zeros((n, J, 3))
    rot = [[None] * J for _ in range(n)]
    for f in range(n):
        for j in range(J):
            local = Rotation.from_quat(np.asarray(motion.rotations[f, j])[[1, 2, 3, 0]])
            p = skel.parents[j]
            if p < 0:
                rot[f][j], pos[f, j] = local, motion.translations[f, j]
            else:
                rot[f][j] = rot[f][p] * local
                pos[f, j] = pos[f, p] + rot[f][p].apply(motion.translations[f, j])
    out = {}
    for key, h, s, fr in (("LH", hand[0], shoulder[0], frame[0]), ("RH", hand[1], shoulder[1], frame[1])):
        rel = np.array([rot[f][fr].inv().apply(pos[f, h] - pos[f, s]) for f in range(n)])
        out[key] = np.linalg.norm(np.gradient(rel, axis=0) * motion.fps, axis=1)
    point = np.array([pos[f, head] + rot[f][head].apply(head_end) for f in range(n)])
    rel = np.array([rot[f][neck_frame].inv().apply(point[f] - pos[f, neck]) for f in range(n)])
    out["Nod"] = np.abs(np.gradient(rel[:, up]) * motion.fps)
    return out


def test_joint_speeds_match_slow_numpy_reference():
    rng = np.random.default_rng(0)
    m = _random_motion(rng)
    got = joint_speeds(m, AP)
    ref = _reference_speeds(m, (INDEX["LeftHand"], INDEX["RightHand"]), (INDEX["LeftArm"], INDEX["RightArm"]),
                            (INDEX["LeftShoulder"], INDEX["RightShoulder"]), INDEX["Head"], INDEX["Neck"],
                            INDEX["Spine2"], np.array([0.0, 9.0, 9.0]))
    for k in ("LH", "RH", "Nod"):
        assert got[k].shape == (m.num_frames,)
        assert ref[k].max() > 1.0  # the case is not degenerate
        np.testing.assert_allclose(got[k], ref[k], rtol=1e-3, atol=1e-3 * ref[k].max(), err_msg=k)


def test_joint_speeds_ignore_torso_and_root_motion():
    """Hands are measured in the shoulder's frame and nods in the neck's parent frame: moving the root
    and the spine must not change them; rotating only the left elbow changes LH alone."""
    rng = np.random.default_rng(1)
    base = _random_motion(rng, root_motion=False, spine_motion=False)
    moved = _random_motion(np.random.default_rng(1), root_motion=True, spine_motion=True)
    for j in range(base.skeleton.num_joints):  # same limb/head rotations, different torso and root
        if j not in (0, INDEX["Spine"], INDEX["Spine1"], INDEX["Spine2"]):
            moved.rotations[:, j] = base.rotations[:, j]
    a, b = joint_speeds(base, AP), joint_speeds(moved, AP)
    for k in ("LH", "RH", "Nod"):
        np.testing.assert_allclose(a[k], b[k], atol=1e-3 * max(1.0, a[k].max()), err_msg=k)
    still = Motion(base.skeleton, np.broadcast_to(base.rotations[:1], base.rotations.shape).copy(),
                   base.translations.copy(), base.fps)
    elbow = still.rotations.copy()
    ang = np.linspace(0, 60, still.num_frames)
    elbow[:, INDEX["LeftForeArm"]] = Rotation.from_euler("X", ang[:, None], degrees=True).as_quat()[:, [3, 0, 1, 2]]
    s = joint_speeds(Motion(still.skeleton, elbow, still.translations, still.fps), AP)
    assert s["LH"].min() > 1.0 and s["RH"].max() < 1e-3 and s["Nod"].max() < 1e-3


def test_nod_is_vertical_head_motion_only():
    skel = seated_skeleton()
    n = 24  # the frame count of the other cases: FK compiles once
    q = np.zeros((n, skel.num_joints, 4))
    q[..., 0] = 1.0
    trans = np.broadcast_to(skel.offsets, (n, skel.num_joints, 3)).copy()
    ang = 20 * np.sin(np.linspace(0, np.pi, n))
    pitch, yaw = q.copy(), q.copy()
    pitch[:, INDEX["Head"]] = Rotation.from_euler("X", ang[:, None], degrees=True).as_quat()[:, [3, 0, 1, 2]]
    yaw[:, INDEX["Head"]] = Rotation.from_euler("Y", ang[:, None], degrees=True).as_quat()[:, [3, 0, 1, 2]]
    nod = joint_speeds(Motion(skel, pitch, trans, 30.0), AP)["Nod"]
    shake = joint_speeds(Motion(skel, yaw, trans, 30.0), AP)["Nod"]
    assert nod.max() > 5.0 and shake.max() < 1e-2 * nod.max()  # shaking the head is no nod


def test_find_joints_names_overrides_and_errors():
    skel = seated_skeleton()
    j = find_joints(skel)
    assert [skel.names[j[k]] for k in ("left_hand", "left_shoulder", "right_hand", "right_shoulder", "neck", "head")] \
        == ["LeftHand", "LeftArm", "RightHand", "RightArm", "Neck", "Head"]
    assert skel.names[find_joints(skel, {"left_hand": r"^LeftForeArm$", "head": None})["left_hand"]] == "LeftForeArm"
    with pytest.raises(ConfigError, match="left_hand"):
        find_joints(skel, {"left_hand": r"^NoSuchJoint$"})
    with pytest.raises(ConfigError, match="unknown joint roles"):
        find_joints(skel, {"tail": "Tail"})


def test_real_bandai_waves_move_the_waving_hand(bandai_dir):
    from convsynth_jax.io import load_bvh

    left = load_bvh(bandai_dir / "dataset-2_wave-left-hand_normal_001.bvh", fps=30)
    right = load_bvh(bandai_dir / "dataset-2_wave-right-hand_normal_001.bvh", fps=30)
    n = min(left.num_frames, right.num_frames)  # one frame count: FK compiles once
    left, right = left.slice(0, n), right.slice(0, n)
    names = left.skeleton.names
    j = find_joints(left.skeleton)
    assert [names[j[k]] for k in ("left_hand", "left_shoulder", "right_hand", "right_shoulder")] == \
        ["Hand_L", "UpperArm_L", "Hand_R", "UpperArm_R"]
    sl, sr = joint_speeds(left, AP), joint_speeds(right, AP)
    assert np.percentile(sl["LH"], 90) > 3 * np.percentile(sl["RH"], 90)
    assert np.percentile(sr["RH"], 90) > 3 * np.percentile(sr["LH"], 90)


# ------------------------------------------------------------------- planted events (tiny corpus)
@pytest.fixture(scope="module")
def tiny(tiny_corpus_dir, tiny_annotations):
    import copy

    ann = copy.deepcopy(tiny_annotations)   # the session's annotation with the default parameters (AP)
    return ann, pd.read_csv(tiny_corpus_dir / "events.csv")


def _overlaps(a, b):
    """For each row of a: does it overlap any row of b (intervals [start, end])?"""
    return np.array([((b["start"] < r.end) & (b["end"] > r.start)).any() for r in a.itertuples()], bool)


def test_detected_motion_events_match_planted(tiny):
    """Precision and recall of window-based detection against planted movements caused by audio
    (spontaneous movements lie away from every audio segment by construction, so the windows
    should not see them: they count for precision only)."""
    ann, ev = tiny
    tp_p = n_p = tp_d = n_d = 0
    for s, parts in ann.items():
        for role, a in parts.items():
            pl = ev[(ev.session == s) & (ev.participant == role) & ev.kind.isin(["LH", "RH", "Nod"])]
            caused = pl[pl.source != "spontaneous"]
            for k in ("LH", "RH", "Nod"):
                d = a.events[a.events.kind == k].drop_duplicates(["start", "end"])
                tp_p += _overlaps(caused[caused.kind == k], d).sum()
                n_p += (caused.kind == k).sum()
                tp_d += _overlaps(d, pl[pl.kind == k]).sum()
                n_d += len(d)
    assert n_p > 100 and n_d > 100
    assert tp_p / n_p >= 0.9 and tp_d / n_d >= 0.9, (tp_p / n_p, tp_d / n_d)


def test_detected_peaks_and_bounds_lie_near_planted(tiny):
    ann, ev = tiny
    errs = []
    for s, parts in ann.items():
        for role, a in parts.items():
            pl = ev[(ev.session == s) & (ev.participant == role) & ev.kind.isin(["LH", "RH"])]
            for r in a.events[a.events.kind.isin(["LH", "RH"])].itertuples():
                cand = pl[(pl.kind == r.kind) & (pl.start < r.end) & (pl.end > r.start)]
                if len(cand):
                    errs.append(np.abs(cand["peak"] - r.peak).min())
            assert (a.events["start"] <= a.events["peak"]).all() and (a.events["peak"] < a.events["end"]).all()
    # the planted stroke (a 90 ms beat on a slower bump) is where the hand is fastest, within a few frames
    assert len(errs) > 50 and np.median(errs) < 0.15


# --------------------------------------------------------------------------- pipeline (shim session)
class _Participant:
    """The participant interface annotate_session uses, without files (no audio: midpoint peaks)."""

    def __init__(self, role, character, motion, words):
        self.role, self.character, self._motion, self._words = role, character, motion, words
        self.audio_path = None

    def load_motion(self, fps):
        return self._motion

    def load_transcript(self):
        return self._words


class _Session:
    def __init__(self, name, participants):
        self.name, self.participants = name, participants


def test_annotate_session_on_shim_participants():
    from convsynth_jax.annotate.pipeline import annotate_corpus, annotate_session
    from convsynth_jax.annotate.types import HP, IDLE, LR, PC

    skel = seated_skeleton()
    n, fps = 24, 10.0  # 2.4 s; 24 frames like the other cases, so FK compiles once
    q = np.zeros((n, skel.num_joints, 4))
    q[..., 0] = 1.0
    trans = np.broadcast_to(skel.offsets, (n, skel.num_joints, 3)).copy()
    t = np.arange(n) / fps
    lift = 40 * np.sin(np.pi * np.clip((t - 0.7) / 0.8, 0, 1)) ** 2  # a left-arm gesture over 0.7-1.5 s
    moving = q.copy()
    moving[:, INDEX["LeftArm"]] = Rotation.from_euler("X", -lift[:, None], degrees=True).as_quat()[:, [3, 0, 1, 2]]
    a_words = pd.DataFrame({"start": [0.8, 1.0, 1.9], "end": [1.0, 1.3, 2.1], "word": ["so", "then", "yeah"]})
    b_words = pd.DataFrame({"start": [1.5], "end": [1.7], "word": ["um"]})
    session = _Session("s1", (_Participant("A", "female", Motion(skel, moving, trans, fps), a_words),
                              _Participant("B", "male", Motion(skel, q.copy(), trans, fps), b_words)))
    ann = annotate_session(session, AP, fps)
    a, b = ann["A"], ann["B"]
    assert a.segments["kind"].tolist() == ["PC", "LR"] and b.segments["kind"].tolist() == ["HP"]
    assert a.partner_segments.equals(b.segments) and b.partner_segments.equals(a.segments)
    assert a.own.label[[5, 10, 14, 20]].tolist() == [IDLE, PC, IDLE, LR]
    assert a.partner.label[16] == HP and b.own.label[16] == HP and b.partner.label[10] == PC
    # PC [0.8, 1.3] s -> frames [8, 13); no audio: peak at the midpoint 1.05 s = frame 10.5, rounded to 10
    assert a.own.seg_start[10] == 8 and a.own.seg_end[10] == 13 and a.own.seg_peak[10] == 10
    lh = a.events[a.events.kind == "LH"]
    assert len(lh) == 1 and lh["segment"].iat[0] == 0 and 0.6 <= lh["start"].iat[0] <= 0.9
    assert b.events.empty  # B never moves
    assert (a.character, b.character, a.session) == ("female", "male", "s1") and a.motion.num_frames == n
    assert list(annotate_corpus(type("C", (), {"sessions": [session]})(), AP, fps,
                                progress=False)) == ["s1"]
