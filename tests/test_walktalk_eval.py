"""walktalk_eval on the small bandai2 fixtures (always) and on the shared data (when present);
config defaults; bad input errors and atomic outputs."""
from __future__ import annotations

import dataclasses
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from convsynth_jax.config import compose, group_params, run_task
from convsynth_jax.errors import ConfigError, WalkTalkError
from convsynth_jax.io.bvh import load_bvh, save_bvh
from convsynth_jax.kinematics import forward_kinematics_np
from convsynth_jax.schema import build_params
from convsynth_jax.walktalk.body import find_body
from convsynth_jax.walktalk.gestures import make_gesture
from convsynth_jax.walktalk.locomotion import extract_loop, seam_foot_slide, tile_loop
from convsynth_jax.walktalk.params import WalkTalkParams

FIXTURES = Path(__file__).resolve().parent / "data" / "walktalk"
COLUMNS = ["gesture", "loop", "gait", "method", "stroke_peak_s", "utterance_peak_s", "shift_s", "peak_in_contact",
           "max_jerk_ratio", "joint_limit_violation_frac", "foot_slide_cm", "elbow_bend_deg"]


def _asdict(x):
    if dataclasses.is_dataclass(x):
        return {f.name: _asdict(getattr(x, f.name)) for f in dataclasses.fields(x)}
    if isinstance(x, (tuple, list)):
        return [_asdict(v) for v in x]
    return x


def test_yaml_defaults_equal_dataclass_defaults():
    cfg = compose(["task=walktalk_eval"])
    from_yaml = group_params(cfg, "walktalk")
    assert _asdict(from_yaml) == _asdict(WalkTalkParams())
    with pytest.raises(ConfigError, match=r"walktalk\.splice\.cc"):
        build_params(WalkTalkParams, {"splice": {"cc": 1.0}}, "walktalk")
    with pytest.raises(WalkTalkError, match="c must be > 0"):
        build_params(WalkTalkParams, {"splice": {"c": -1.0}}, "walktalk")


def test_fixture_size_and_licence():
    files = list(FIXTURES.glob("*.bvh"))
    assert len(files) == 4 and sum(f.stat().st_size for f in files) < 300 * 1024
    text = (FIXTURES / "LICENSE").read_text()
    assert "Kobayashi et al." in text and "arXiv:2306.08861" in text and "CC BY-NC 4.0" in text


def test_fixture_loops_seamless_and_gestures_single_peak():
    from convsynth_jax.walktalk.params import GaitParams, PhaseParams

    for pat, gait in (("*_walk_normal_*", "walk"), ("*_run_normal_*", "jog")):
        m = load_bvh(next(FIXTURES.glob(pat + ".bvh")))
        lp = extract_loop(m, GaitParams())
        assert lp.gait == gait and lp.contact[0]
        tiled = tile_loop(lp, 4 * lp.num_frames)
        assert seam_foot_slide(tiled, lp.num_frames, GaitParams()) <= 2.0
    for f in FIXTURES.glob("*raise-up*.bvh"):
        g = make_gesture(load_bvh(f), GaitParams(), PhaseParams())
        assert g.single_peak


def test_walktalk_eval_on_fixtures(tmp_path):
    cfg = compose(["task=walktalk_eval", f"walktalk.data_dir={FIXTURES}", "task.loops_per_gait=1"])
    summary = run_task(cfg, tmp_path)
    df = pd.read_csv(tmp_path / "walktalk_eval.csv")
    assert list(df.columns[:len(COLUMNS)]) == COLUMNS
    assert len(df) == 2 * 2 * 3  # gestures x gaits x methods
    synced = df[df["method"] == "stylized+synced"]
    assert synced["peak_in_contact"].all()
    assert synced["peak_in_contact_alt"].all()
    assert ((synced["shift_s"] <= 0) & (synced["shift_s"] >= -0.6)).all()
    assert (df["stroke_peak_s"] <= df["utterance_peak_s"]).all()
    assert (df["foot_slide_cm"] <= 2.0).all()
    # the summary's rates are the rows' means; the loops' contact fractions per gait
    rates = {(r["gait"], r["method"]): r for r in summary["per_gait_method"]}
    for (gait, method), r in rates.items():
        d = df[(df["method"] == method) & ((df["gait"] == gait) | (gait == "all"))]
        assert r["peak_in_contact_rate"] == pytest.approx(d["peak_in_contact"].mean())
        assert r["peak_in_contact_alt_rate"] == pytest.approx(d["peak_in_contact_alt"].mean())
    assert 0.35 <= summary["loop_contact"]["walk"]["contact_frac_mean"] <= 0.65
    assert (df.loc[df["method"] != "naive", "dof_within_csigma"]).all()
    # the loop-alone baseline covers the same frames for the unsynchronized methods
    assert df["loop_violation_frac"].between(0, 1).all()
    assert (df["new_violation_frac"] <= df["joint_limit_violation_frac"] + 1e-12).all()
    unsynced = df[df["method"] != "stylized+synced"]
    assert (unsynced.groupby(["gesture", "gait"])["loop_violation_frac"].nunique() == 1).all()
    for name in ("walktalk_eval_summary.csv", "walktalk_peak_phase.png", "walktalk_elbow.png",
                 "walktalk_contact_sheet.png", "walktalk_gait_phases.png", "summary.json"):
        assert (tmp_path / name).stat().st_size > 0
    assert summary["splices"] == 12
    # both joint-limit readings, per gait x method, against the per-splice rows
    readings = {(r["gait"], r["method"]): r for r in summary["joint_limit_readings"]}
    assert set(readings) == {(g, m) for g in ("walk", "jog") for m in ("naive", "stylized", "stylized+synced")}
    for (gait, method), r in readings.items():
        d = df[(df["gait"] == gait) & (df["method"] == method)]
        assert r["per_frame"]["value"] == pytest.approx(d["joint_limit_violation_frac"].mean())
        assert r["per_cell"]["value"] == pytest.approx(d["limit_cell_frac"].mean())
        assert r["met_per_frame"] == (r["per_frame"]["le_naive"] and r["per_frame"]["value"] < 0.01)
    assert summary["limit_table_clips"] == {"walk": 1, "jog": 1, "gesture": 2}


def test_spliced_lower_body_equals_locomotion_on_real_fixture():
    from convsynth_jax.walktalk.params import GaitParams, PhaseParams, SpliceParams
    from convsynth_jax.walktalk.pipeline import (
        gesture_context,
        loop_context,
        splice_gesture,
    )

    m = load_bvh(next(FIXTURES.glob("*_run_normal_*.bvh")))
    body = find_body(m.skeleton)
    lc = loop_context(extract_loop(m, GaitParams()), body)
    gc = gesture_context(make_gesture(load_bvh(next(FIXTURES.glob("*raise-up-right*.bvh"))), GaitParams(),
                                      PhaseParams()), body)
    T = 220
    r = splice_gesture(lc, gc, 3.5, T, SpliceParams(), "stylized+synced")
    loco = tile_loop(lc.loop, T)
    keep = [j for j in range(m.skeleton.num_joints) if j not in body.arm_r]
    np.testing.assert_allclose(r.motion.rotations[:, keep], loco.rotations[:, keep], atol=1e-6)
    pa, pb = forward_kinematics_np(r.motion), forward_kinematics_np(loco)
    for j in body.lower:
        np.testing.assert_allclose(pa[:, j], pb[:, j], atol=1e-3)


def test_eval_on_shared_data_subset(tmp_path, bandai_dir):
    cfg = compose(["task=walktalk_eval", f"walktalk.data_dir={bandai_dir}", "task.loops_per_gait=2",
                   "task.max_gestures=12", "task.figures=false"])
    run_task(cfg, tmp_path)
    df = pd.read_csv(tmp_path / "walktalk_eval.csv")
    synced = df[df["method"] == "stylized+synced"]
    assert synced["peak_in_contact"].mean() >= 0.95
    assert synced["peak_in_contact_alt"].mean() >= 0.95
    assert ((synced["shift_s"] <= 0) & (synced["shift_s"] >= -0.6)).all()
    assert (df["foot_slide_cm"] <= 2.0).all()


# ---------------------------------------------------------------- bad input


def _data_dir_with(tmp_path, extra: dict) -> Path:
    d = tmp_path / "data"
    d.mkdir()
    for f in FIXTURES.glob("*.bvh"):
        shutil.copy(f, d / f.name)
    for name, motion in extra.items():
        save_bvh(motion, d / name)
    return d


def test_travelling_gesture_clip_is_rejected_and_nothing_written(tmp_path):
    walk = load_bvh(next(FIXTURES.glob("*_walk_normal_*.bvh")))
    d = _data_dir_with(tmp_path, {"dataset-2_raise-up-fake_normal_999.bvh": walk})
    out = tmp_path / "out"
    cfg = compose(["task=walktalk_eval", f"walktalk.data_dir={d}", "task.loops_per_gait=1"])
    with pytest.raises(WalkTalkError, match="not standing") as e:
        run_task(cfg, out)
    assert "raise-up-fake" in str(e.value) and "frame" in str(e.value)
    assert not (out / "walktalk_eval.csv").exists()


def test_short_locomotion_clip_lists_strikes():
    from convsynth_jax.walktalk.params import GaitParams

    walk = load_bvh(next(FIXTURES.glob("*_walk_normal_*.bvh")))
    with pytest.raises(WalkTalkError, match=r"left heel strikes at frames \[\d+") as e:
        extract_loop(walk.slice(0, 45), GaitParams())
    assert "walk_normal_001" in str(e.value)


def test_gesture_with_other_skeleton_is_rejected(tmp_path):
    g = load_bvh(next(FIXTURES.glob("*raise-up-right*.bvh")))
    sk = g.skeleton
    other = dataclasses.replace(g, skeleton=dataclasses.replace(sk, names=tuple(
        "Wrist_R" if n == "Hand_R" else n for n in sk.names)))
    d = _data_dir_with(tmp_path, {"dataset-2_raise-up-odd_normal_998.bvh": other})
    cfg = compose(["task=walktalk_eval", f"walktalk.data_dir={d}", "task.loops_per_gait=1"])
    with pytest.raises(WalkTalkError, match=r"missing joints \['Hand_R'\]"):
        run_task(cfg, tmp_path / "out")


def test_phase_csv_override_and_out_of_order(tmp_path):
    csv = tmp_path / "phases.csv"
    stem = next(FIXTURES.glob("*raise-up-right*.bvh")).stem
    csv.write_text(f"gesture,t_pb,t_pe,t_sb,t_se,t_rb,t_re,peaks,handedness,type\n{stem},0.1,0.3,0.2,1.0,1.1,1.6,0.5,r,beat\n")
    cfg = compose(["task=walktalk_eval", f"walktalk.data_dir={FIXTURES}", f"walktalk.phases_csv={csv}",
                   "task.loops_per_gait=1"])
    with pytest.raises(WalkTalkError, match="out of order") as e:
        run_task(cfg, tmp_path / "out")
    assert "phases.csv line 2" in str(e.value)
    csv.write_text(f"gesture,t_pb,t_pe,t_sb,t_se,t_rb,t_re,peaks\n{stem},0.1,0.3,0.4,1.0,1.1,1.6,0.5\n")
    run_task(cfg, tmp_path / "ok")
    from convsynth_jax.walktalk.library import load_library

    lib = load_library(build_params(WalkTalkParams, {"phases_csv": str(csv), "splice": {"transition_pad_s": 0.0}}), FIXTURES, 1)
    g = next(gc.gesture for gc in lib.gestures if Path(gc.gesture.name).stem == stem)
    assert (g.phases.pb, g.phases.pe, g.phases.sb, g.phases.se, g.phases.rb, g.phases.re) == (3, 9, 12, 30, 33, 48)
    assert g.phases.peaks == (15,) and g.handedness == "r"


def test_stylized_strokes_stay_within_joint_limits_on_fixtures():
    """Defect: with c = 3 the stylization band of a jog loop (elbows already flexed ~90 deg) reached
    past any flexion in the clips, so raise-hand strokes were spliced with the elbow folded beyond
    its limit (jog stylized violations 42% vs naive 5% on bandai2). The band is now also cut at
    the library's range of motion; the elbow bounce is rescaled into it as well. The paper's band
    alone (respect_joint_limits=False) still leaves the limits on the jog fixture."""
    from convsynth_jax.walktalk.library import dof_limits, load_library
    from convsynth_jax.walktalk.pipeline import splice_gesture
    from convsynth_jax.walktalk.splice import joint_euler

    p = WalkTalkParams()
    lib = load_library(p, FIXTURES, 1, single_peak_only=True)
    rom, scored = dof_limits(lib), dof_limits(lib, (0.5, 99.5), 0.5)
    paper = dataclasses.replace(p.splice, respect_joint_limits=False)
    for gait in ("walk", "jog"):
        lc = lib.loops[gait][0]
        for gc in lib.gestures:
            for method in ("stylized", "stylized+synced"):
                r = splice_gesture(lc, gc, 4.0, 220, p.splice, method, limits=rom)
                e = joint_euler(r.motion.slice(r.phases.sb, r.phases.se + 1), gc.joints)
                assert not scored.violations(e, gc.joints).any(), (gait, gc.gesture.name, method)
                # still within the paper's +- c sigma
                st = lc.stats.mean[[lc.joints.index(j) for j in gc.joints]]
                sd = lc.stats.std[[lc.joints.index(j) for j in gc.joints]]
                assert np.all(np.abs(r.styled_euler - st) <= p.splice.c * sd + 1e-4)
            if gait == "jog":
                r = splice_gesture(lc, gc, 4.0, 220, paper, "stylized", limits=rom)
                e = joint_euler(r.motion.slice(r.phases.sb, r.phases.se + 1), gc.joints)
                assert scored.violations(e, gc.joints).any(axis=(1, 2)).mean() > 0.5


def test_in_sample_violation_floor_planted():
    """One DOF of the left arm spread evenly over 1000 frames, every other DOF constant: the
    0.5-99.5 percentile limits leave out 5 + 5 frames, so 1% of the left arm's frames (0.5% as the
    mean of both arms) violate in-sample; 0-100 percentiles leave none."""
    from convsynth_jax.walktalk.library import dof_limits, load_library
    from convsynth_jax.walktalk.limit_metrics import in_sample_violations

    lib = load_library(WalkTalkParams(), FIXTURES, 1, single_peak_only=True)
    a = len(dof_limits(lib).joints)
    x = np.zeros((1000, a, 3))
    x[:, 1, 2] = np.linspace(-0.5, 0.5, 1000)   # joint row 1 is in the left arm (shoulder first)
    lib = dataclasses.replace(lib, source_euler=[x], source_kind=["walk"])
    got = in_sample_violations(lib, dof_limits(lib, (0.5, 99.5)))
    assert got["walk"]["frames"] == 1000
    np.testing.assert_allclose(got["walk"]["one_arm_frac"], 0.005, atol=1e-3)
    np.testing.assert_allclose(got["all"]["both_arms_frac"], 0.01, atol=2e-3)
    assert in_sample_violations(lib, dof_limits(lib, (0.0, 100.0)))["all"]["both_arms_frac"] == 0.0
    # with a torso radius: the left hand planted inside on 20 other frames; the per-frame reading of
    # a one-handed splice on the clip itself is then (10 + 20) / 1000 (left), 20 / 1000 (right)
    d = np.full((1000, 2), 30.0)
    d[100:120, 0] = 5.0
    lib = dataclasses.replace(lib, source_torso=[d])
    got = in_sample_violations(lib, dof_limits(lib, (0.5, 99.5)), 10.0)["walk"]
    assert got["hand_in_torso_frac"] == pytest.approx(0.02)
    assert got["frame_reading_frac"] == pytest.approx(0.025, abs=1e-3)
    assert got["frame_reading_clip_median"] == got["frame_reading_frac"] and got["clips_ge_1pct"] == 1.0
    assert "hand_in_torso_frac" not in in_sample_violations(lib, dof_limits(lib))["walk"]


def test_elbow_tracking_follows_the_loop_on_fixtures():
    """Stylized strokes bend the elbow more on the jog loop (elbows ~90 deg) than on the walk loop;
    naive strokes are the same on both (the gesture's own elbow)."""
    from convsynth_jax.walktalk.elbow import elbow_tracking, elbow_tracking_summary
    from convsynth_jax.walktalk.library import load_library

    p = WalkTalkParams()
    lib = load_library(p, FIXTURES, 1, single_peak_only=True)
    df = elbow_tracking(lib, p, methods=("naive", "stylized"))
    assert len(df) == len(lib.gestures) * 2 * 2
    w = df.pivot_table(index=["gesture", "method"], columns="gait", values="bend")
    lb = df.groupby("gait")["loop_bend"].first()
    assert lb["jog"] > lb["walk"] + 20
    for g in df["gesture"].unique():
        assert w.loc[(g, "stylized"), "jog"] > w.loc[(g, "stylized"), "walk"] + 10
        assert abs(w.loc[(g, "naive"), "jog"] - w.loc[(g, "naive"), "walk"]) < 1.0
    s = {(r["gait"], r["method"]): r for r in elbow_tracking_summary(df)}
    assert s[("all", "stylized")]["elbow_corr_pooled"] > 0.9


def test_limit_cells_count_spliced_dofs_on_blended_frames():
    """The cell reading of the joint-limit metric (ours): DOF x frame cells of the gesturing arm over
    t_Pb < t < t_Re, exactly the frames whose Eq. 2 weight is > 0 (both eases), and only the
    gesturing hand in the torso test. Planted: limits that one DOF leaves on known frames, the idle
    hand kept inside the torso cylinder."""
    from convsynth_jax.walktalk.gestures import Phases
    from convsynth_jax.walktalk.limit_metrics import LimitCheck, ScoredSpan, limit_cells, limit_violations
    from convsynth_jax.walktalk.splice import JointLimits, joint_euler, splice_weights

    m = load_bvh(next(FIXTURES.glob("*raise-up-right-hand*.bvh")))
    body = find_body(m.skeleton)
    ph = Phases(5, 9, 10, 30, 31, 45, (20,))
    for ease in ("linear", "smootherstep"):
        assert np.flatnonzero(splice_weights(m.num_frames, ph, ease) > 0).tolist() == list(range(ph.pb + 1, ph.re))
    joints = tuple(body.arm("r"))
    e = joint_euler(m, joints)
    x = e[:, 2, 0]                                    # the forearm's first channel
    thr = np.median(x[ph.pb:ph.re + 1])
    lo = np.full((len(joints), 3), -10.0)
    hi = np.full((len(joints), 3), 10.0)
    hi[2, 0] = thr
    lim = JointLimits(joints, np.zeros((len(joints), 3)), lo, hi)
    pos = forward_kinematics_np(m)
    span = ScoredSpan(m, pos, ph, joints, ("r",))
    cells, torso = limit_cells(span, LimitCheck(body, lim, 0.0))
    inner = np.arange(ph.pb + 1, ph.re)
    want = np.zeros((len(inner), len(joints), 3), bool)
    want[:, 2, 0] = x[inner] > thr
    np.testing.assert_array_equal(cells, want)
    assert 0 < cells.mean() < 1.0 / (len(joints) * 3) and not torso.any()
    # the frame reading counts a frame when any DOF is out, on t_Pb..t_Re
    dof_bad, _ = limit_violations(span, LimitCheck(body, lim, 0.0))
    # given the span's Euler angles over t_Pb..t_Re, the same
    with_euler = span._replace(euler=e[ph.pb:ph.re + 1])
    np.testing.assert_array_equal(limit_violations(with_euler, LimitCheck(body, lim, 0.0)).dof, dof_bad)
    np.testing.assert_array_equal(limit_cells(with_euler, LimitCheck(body, lim, 0.0)).cells, cells)
    np.testing.assert_array_equal(dof_bad, x[ph.pb:ph.re + 1] > thr)
    # the torso test: a radius that swallows every hand counts the gesturing one only in the cells
    _, torso = limit_cells(span, LimitCheck(body, lim, 1e4))
    assert torso.all() and len(torso) == len(inner)


def test_elbow_partial_corr_planted():
    """Planted loops whose mean bend and spread anti-correlate and strokes at mean + 2.5 spread (the
    saturated c-sigma rescale): the plain correlation with the mean is poor, the partial one given
    the spread is 1 with slope 1; a stroke that does not move (naive) counts as 0."""
    from convsynth_jax.walktalk.elbow import _per_gesture_corr, elbow_partial_corr

    rng = np.random.default_rng(2)
    mean = rng.normal(90, 7, 30)
    sd = 12 - 0.4 * (mean - 90) + rng.normal(0, 0.5, 30)
    rows = []
    for g, off in (("g1", 0.0), ("g2", 3.0)):
        for i in range(30):
            rows.append({"gesture": g, "loop_elbow_bend_deg": mean[i], "loop_elbow_bend_sd_deg": sd[i],
                         "elbow_bend_deg": mean[i] + 2.5 * sd[i] + off})
    d = pd.DataFrame(rows)
    plain = _per_gesture_corr(d)
    corr, slope = elbow_partial_corr(d)
    assert max(plain) < 0.5
    np.testing.assert_allclose(corr, 1.0, atol=1e-9)
    np.testing.assert_allclose(slope, 1.0, atol=1e-9)
    naive = d.assign(elbow_bend_deg=50.0)
    assert _per_gesture_corr(naive) == [0.0, 0.0] and elbow_partial_corr(naive) == ([0.0, 0.0], [0.0, 0.0])


def test_loop_bend_is_kept_by_its_loop_context(monkeypatch):
    """lc_bend's cache lives on the loop context it describes (no process-wide cache keyed by id(),
    whose ids come back for other loops once a context is freed): two loops never share a value, and
    a context built again from the same loop (dataclasses.replace) computes its own."""
    import dataclasses

    from convsynth_jax.walktalk import elbow
    from convsynth_jax.walktalk.params import GaitParams
    from convsynth_jax.walktalk.pipeline import loop_context

    monkeypatch.setattr(elbow, "id", lambda x: 1, raising=False)   # were anything keyed by id, all would collide
    walk = extract_loop(load_bvh(next(FIXTURES.glob("*_walk_normal_*.bvh"))), GaitParams())
    run = extract_loop(load_bvh(next(FIXTURES.glob("*_run_normal_*.bvh"))), GaitParams())
    a, b = loop_context(walk), loop_context(run)
    bend_a, bend_b = elbow.lc_bend(a, "r"), elbow.lc_bend(b, "r")
    assert abs(bend_a - bend_b) > 20     # walking vs running elbows
    assert elbow.lc_bend(a, "r") == bend_a
    assert set(a.elbow_bend) == {"r"} and a.elbow_bend is not b.elbow_bend
    c = dataclasses.replace(a, gait_min_std=None)
    assert c.elbow_bend == {} and elbow.lc_bend(c, "r") == bend_a


def test_joint_limits_pool_every_clip_walk_turns_included(tmp_path):
    """Defect: the limits are the per-DOF 0.5-99.5 percentile over all clips, and the clips are
    walk, walk-turn, run and the gesture clips, but the table pooled only the clips the system
    splices (walks, runs, gestures): walk-turns were left out. ``walktalk.limit_globs`` (default
    the walk-turns) adds them to the table only. Planted: a walk-turn copy of the walk fixture
    with the left forearm folded 100 deg more widens that DOF's limits; it is not used as a loop."""
    from convsynth_jax.walktalk.library import dof_limits, load_library

    for f in FIXTURES.glob("*.bvh"):
        shutil.copy(f, tmp_path / f.name)
    walk = load_bvh(next(FIXTURES.glob("*_walk_normal_*.bvh")), fps=30.0)
    body = find_body(walk.skeleton)
    j = body.joints["elbow_l"]
    from scipy.spatial.transform import Rotation

    rot = np.array(walk.rotations, dtype=np.float64)
    extra = Rotation.from_euler("x", 100.0, degrees=True)
    rot[:, j] = (Rotation.from_quat(rot[:, j][:, [1, 2, 3, 0]]) * extra).as_quat()[:, [3, 0, 1, 2]]
    save_bvh(dataclasses.replace(walk, rotations=rot), tmp_path / "dataset-2_walk-turn-left_normal_001.bvh")
    p = WalkTalkParams()
    lib = load_library(p, tmp_path, 1, single_peak_only=True)
    assert lib.source_kind.count("limits only") == 1
    assert len(lib.loops["walk"]) == 1 and "walk-turn" not in lib.loops["walk"][0].loop.source
    without = load_library(dataclasses.replace(p, limit_globs=()), tmp_path, 1, single_peak_only=True)
    assert "limits only" not in without.source_kind
    a, b = dof_limits(lib), dof_limits(without)
    row = a.joints.index(j)
    assert (a.hi[row] - a.lo[row]).max() > (b.hi[row] - b.lo[row]).max() + np.radians(10)


def test_torso_check_calibrated_so_recorded_clips_are_never_inside(tmp_path):
    """Defect: the hands-in-the-torso part of the joint-limit metric was a fixed 12 cm capsule about
    the hips-neck segment, and it fired on unmodified recordings: a recorded jogger's right wrist
    swings to 10.1 cm of that axis (bandai2 run 047, the excerpt in tests/data; 0.8% of all run
    hand-frames). A clip cannot put its hand inside its own torso, so those were false positives.
    The radius is now calibrated from the library's recordings (evaluate.torso_radius, quantile 0
    by default): no frame of any recorded clip is inside; a fixed radius is still an option, and a
    hand planted on the spine axis is still inside."""
    from convsynth_jax.walktalk.evaluate import EvalParams, torso_radius
    from convsynth_jax.walktalk.gestures import Phases
    from convsynth_jax.walktalk.library import dof_limits, load_library
    from convsynth_jax.walktalk.limit_metrics import LimitCheck, ScoredSpan, in_sample_violations, limit_violations
    from convsynth_jax.walktalk.torso import hand_torso_distance

    for f in FIXTURES.glob("*.bvh"):
        shutil.copy(f, tmp_path / f.name)
    excerpt = Path(__file__).resolve().parent / "data" / "dataset-2_run_normal_047_f68-88.bvh"
    shutil.copy(excerpt, tmp_path / excerpt.name)
    lib = load_library(WalkTalkParams(), tmp_path, 1, single_peak_only=True)
    assert len(lib.source_torso) == len(lib.source_euler) == 5
    closest = min(float(d.min()) for d in lib.source_torso)
    assert 10.0 < closest < 10.3
    # the old proxy flags the recording itself
    old = EvalParams(torso_radius_cm=12.0)
    assert torso_radius(lib, old) == 12.0
    assert in_sample_violations(lib, dof_limits(lib), 12.0)["jog"]["hand_in_torso_frac"] > 0
    # the calibrated one (the evaluation's default) flags no recorded frame
    radius = torso_radius(lib, EvalParams())
    assert radius == pytest.approx(closest)
    got = in_sample_violations(lib, dof_limits(lib), radius)
    assert all(v["hand_in_torso_frac"] == 0.0 for v in got.values())
    m = load_bvh(excerpt, fps=30.0)
    pos = forward_kinematics_np(m)
    ph = Phases(0, 4, 5, 12, 13, m.num_frames - 1, (8,))
    joints = lib.body.arm("r")
    lim = dof_limits(lib)
    span = ScoredSpan(m, pos, ph, joints, ("r",))
    assert limit_violations(span, LimitCheck(lib.body, lim, 12.0)).torso.any()
    assert not limit_violations(span, LimitCheck(lib.body, lim, radius)).torso.any()
    # a hand on the torso axis is inside at the calibrated radius
    planted = pos.copy()
    b = lib.body.joints
    planted[3, b["hand_l"]] = 0.5 * (pos[3, b["hips"]] + pos[3, b["neck"]])
    d = hand_torso_distance(planted, lib.body)
    assert d[3, 0] < 1e-9 and limit_violations(span._replace(positions=planted), LimitCheck(lib.body, lim, radius)).torso[3]
    with pytest.raises(ConfigError, match="torso_radius_quantile"):
        torso_radius(lib, EvalParams(torso_radius_quantile=1.5))
    with pytest.raises(ConfigError, match="torso_radius_cm"):
        torso_radius(lib, EvalParams(torso_radius_cm=-1.0))
    # through the task: the radius and the recordings' own rates land in summary.json
    cfg = compose(["task=walktalk_eval", f"walktalk.data_dir={tmp_path}", "task.loops_per_gait=1",
                   "task.figures=false", "task.methods=[naive]"])
    summary = run_task(cfg, tmp_path / "out")
    assert summary["torso_radius_cm"] == pytest.approx(closest)
    assert summary["limits_in_sample_violation"]["jog"]["hand_in_torso_frac"] == 0.0


def test_source_readings_against_a_frame_by_frame_reference():
    """limit_metrics.source_readings scores the unmodified loops (one arm at a time, either hand in the
    torso) and gestures (t_Pb..t_Re, the gesturing arm(s)) as the per-frame and cell readings score
    a splice; checked against a plain loop over frames, with a radius that puts some frames inside."""
    from convsynth_jax.walktalk.library import dof_limits, load_library
    from convsynth_jax.walktalk.limit_metrics import source_readings

    lib = load_library(WalkTalkParams(), FIXTURES, 1, single_peak_only=True)
    lim = dof_limits(lib)
    body = lib.body
    radius = 17.0   # between the fixtures' closest hands (15.5 cm) and most frames

    def inside(pos_t):
        a, b = pos_t[body.joints["hips"]], pos_t[body.joints["neck"]]
        for s in ("l", "r"):
            h = pos_t[body.joints[f"hand_{s}"]]
            t = min(max(np.dot(h - a, b - a) / np.dot(b - a, b - a), 0.0), 1.0)
            if np.linalg.norm(h - (a + t * (b - a))) < radius:
                return True
        return False

    def out_of_limits(eu_t, joints):
        return lim.violations(eu_t[None], joints)[0]

    got = source_readings(lib, lim, radius)
    for gait, lcs in lib.loops.items():
        lc = lcs[0]
        pos = forward_kinematics_np(lc.loop.motion)
        frames, cells = [], []
        for s in ("l", "r"):
            rows = [lc.joints.index(j) for j in body.arm(s)]
            js = [lc.joints[i] for i in rows]
            bad = [out_of_limits(lc.euler[t, rows], js) for t in range(len(pos))]
            frames.append(np.mean([b.any() or inside(pos[t]) for t, b in enumerate(bad)]))
            cells.append(np.mean(bad))
        assert got[f"loops_{gait}"]["per_frame"]["mean"] == pytest.approx(np.mean(frames))
        assert got[f"loops_{gait}"]["per_cell"]["mean"] == pytest.approx(np.mean(cells))
    frames, cells = [], []
    for gc in lib.gestures:
        g = gc.gesture
        pos = forward_kinematics_np(g.motion)
        ph = g.phases
        frames.append(np.mean([out_of_limits(gc.euler[t], gc.joints).any() or inside(pos[t])
                               for t in range(ph.pb, ph.re + 1)]))
        cells.append(np.mean([out_of_limits(gc.euler[t], gc.joints) for t in range(ph.pb + 1, ph.re)]))
    assert got["gestures"]["per_frame"]["mean"] == pytest.approx(np.mean(frames))
    assert got["gestures"]["per_cell"]["mean"] == pytest.approx(np.mean(cells))
    assert 0 < got["loops_jog"]["per_frame"]["mean"] < 1
    none_inside = source_readings(lib, lim, 0.0)
    assert none_inside["loops_jog"]["per_frame"]["mean"] < got["loops_jog"]["per_frame"]["mean"]
    assert none_inside["loops_jog"]["per_cell"] == got["loops_jog"]["per_cell"]


def test_limit_readings_report_both_readings_against_naive():
    """limit_metrics.limit_readings: per gait x method, the frame and the cell reading of the joint-limit
    acceptance, each with the loop alone and naive, "<= naive" and "< 1%" decided per reading.
    Planted rows: jog stylized is under naive in both readings but over 1% per frame, while what it
    introduces over its own loop is under 1% (the excess reading); walk stylized is over naive per
    cell; the gait "all" is left out."""
    from convsynth_jax.walktalk.limit_metrics import limit_readings

    def row(gait, method, frame, cell, torso=0.0, new=0.0, new_cell=0.0):
        return {"gait": gait, "method": method, "violation_frac_mean": frame, "loop_violation_frac_mean": 0.2,
                "limit_cell_frac_mean": cell, "loop_limit_cell_frac_mean": 0.01,
                "hand_in_torso_gesturing_frac_mean": torso, "loop_hand_in_torso_gesturing_frac_mean": 0.02,
                "new_violation_frac_mean": new, "new_limit_cell_frac_mean": new_cell}

    rows = [row("jog", "naive", 0.06, 0.003, 0.008, 0.02, 0.001), row("jog", "stylized", 0.05, 0.002, 0.006, 0.004),
            row("walk", "naive", 0.01, 0.0005), row("walk", "stylized", 0.003, 0.0009), row("all", "naive", 0.1, 0.1)]
    got = {(r["gait"], r["method"]): r for r in limit_readings(rows)}
    assert set(got) == {("jog", "naive"), ("jog", "stylized"), ("walk", "naive"), ("walk", "stylized")}
    js = got[("jog", "stylized")]
    assert js["per_frame"] == {"value": 0.05, "loop_alone": 0.2, "naive": 0.06, "introduced": 0.004,
                               "introduced_naive": 0.02, "le_naive": True, "lt_1pct": False,
                               "introduced_lt_1pct": True}
    assert js["met_per_frame_introduced"] and not js["met_per_frame"]
    assert js["per_cell"]["introduced_naive"] == 0.001
    assert js["per_cell"]["le_naive"] and js["per_cell"]["lt_1pct"] and js["per_cell"]["hand_in_torso_naive"] == 0.008
    assert (js["met_per_frame"], js["met_per_cell"]) == (False, True)
    ws = got[("walk", "stylized")]
    assert (ws["met_per_frame"], ws["met_per_cell"]) == (True, False)
    assert got[("walk", "naive")]["per_frame"]["lt_1pct"] is False   # 0.01 is not < 1%


def test_elbow_tracking_variants_and_loop_measures_on_fixtures():
    """elbow.elbow_tracking with ``variants`` (an elbow study goes through it, not a copy of the
    loop): one row per gesture x loop x variant named by the variant; the paper's
    band without the range-of-motion cut is within 1 deg of the default's stylized rows on the walk
    fixture (whose band barely meets the limits) and > 1 deg off on jog (cut at ~120 deg); ``loop_measures`` adds the bend of
    the mean pose and of the loop over the stroke's frames, close to the loop's mean bend."""
    from convsynth_jax.walktalk.elbow import elbow_tracking
    from convsynth_jax.walktalk.library import load_library

    p = WalkTalkParams()
    lib = load_library(p, FIXTURES, 1, single_peak_only=True)
    variants = {"default": (p.splice, "stylized"),
                "paper band": (dataclasses.replace(p.splice, respect_joint_limits=False), "stylized")}
    df = elbow_tracking(lib, p, variants=variants, loop_measures=True)
    assert len(df) == len(lib.gestures) * 2 * 2 and set(df["method"]) == set(variants)
    plain = elbow_tracking(lib, p, methods=("stylized",))
    d = df[df["method"] == "default"].reset_index(drop=True)
    np.testing.assert_allclose(d["bend"], plain["bend"])
    w = df.pivot_table(index=["gesture", "gait"], columns="method", values="bend")
    assert np.allclose(w.xs("walk", level="gait")["default"], w.xs("walk", level="gait")["paper band"], atol=1.0)
    assert (np.abs(w.xs("jog", level="gait")["default"] - w.xs("jog", level="gait")["paper band"]) > 1.0).all()
    assert (np.abs(df["loop_pose_bend"] - df["loop_bend"]) < 10).all()
    assert (np.abs(df["loop_phase_bend"] - df["loop_bend"]) < 25).all()


def test_quality_preset_sets_our_splice_options_and_paper_keeps_the_papers():
    """preset=quality turns on our three stylization options (docs/presets.md) and nothing else of
    walktalk; preset=paper (the default) leaves every walktalk value at the paper's (the dataclass
    defaults: one std per loop, the hard range-of-motion cut, one rescale factor per DOF)."""
    def walktalk(*overrides):
        return group_params(compose(["task=walktalk_eval", *overrides]), "walktalk")

    paper, default = walktalk("preset=paper"), walktalk()
    assert _asdict(paper) == _asdict(default) == _asdict(WalkTalkParams())
    assert (paper.splice.band_std, paper.splice.joint_limit_mode, paper.splice.rescale_coupling) == ("loop", "hard", 0.0)
    quality = walktalk("preset=quality")
    assert quality.splice.band_std == "gait_min" and quality.splice.joint_limit_mode == "soft"
    assert 0.0 < quality.splice.rescale_coupling <= 1.0
    back = dataclasses.replace(quality, splice=dataclasses.replace(quality.splice, band_std="loop", joint_limit_mode="hard",
                                                                   rescale_coupling=0.0))
    assert _asdict(back) == _asdict(paper)
    # a key after the preset still wins
    assert walktalk("preset=quality", "walktalk.splice.rescale_coupling=0.5").splice.rescale_coupling == 0.5


def test_gesture_reach_per_gait_and_variant_against_the_base():
    """elbow.gesture_reach on the fixtures: one reach per gesture and loop for every variant, the base
    variant's ratio to itself is 1, a second copy of the base reads the same, every reach finite and
    positive."""
    from convsynth_jax.walktalk.elbow import gesture_reach
    from convsynth_jax.walktalk.library import load_library

    p = WalkTalkParams()
    lib = load_library(p, FIXTURES, 1, single_peak_only=True)
    variants = {"naive": (p.splice, "naive"), "stylized": (p.splice, "stylized+synced"),
                "copy": (p.splice, "stylized+synced")}
    rows = {(r["gait"], r["variant"]): r for r in gesture_reach(lib, p, variants, "stylized", every=1)}
    assert {g for g, _ in rows} == set(lib.loops)
    for gait in lib.loops:
        assert rows[gait, "stylized"]["ratio_to_base_median"] == pytest.approx(1.0)
        assert rows[gait, "copy"]["reach_cm_median"] == pytest.approx(rows[gait, "stylized"]["reach_cm_median"])
        assert rows[gait, "naive"]["splices"] == rows[gait, "stylized"]["splices"] == len(lib.gestures)
        assert all(np.isfinite(r["reach_cm_median"]) and r["reach_cm_median"] > 0 for r in rows.values())


def test_goal_rows_one_per_setting_and_gait_sharing_the_naive_run():
    """evaluate.goal_rows on the fixtures: a row per setting and gait, counts within the splices, the
    naive rows computed once and reusable (a second call given them reads the same)."""
    import json

    from convsynth_jax.walktalk.evaluate import goal_rows
    from convsynth_jax.walktalk.library import load_library

    p = WalkTalkParams()
    lib = load_library(p, FIXTURES, 1, single_peak_only=True)
    settings = {"paper defaults": {}, "coupled": {"rescale_coupling": 1.0}}
    rows, naive = goal_rows(lib, p, settings)
    assert [(r["setting"], r["gait"]) for r in rows] == [(s, g) for s in settings for g in lib.loops]
    for r in rows:
        assert r["splices"] == len(lib.gestures) and 0 <= r["jerk_over_2x"] <= r["splices"]
        assert 0 <= r["naive_jerk_over_2x"] <= r["splices"] and 0.0 <= r["peak_in_contact_rate"] <= 1.0
    again, _ = goal_rows(lib, p, {"paper defaults": {}}, naive_df=naive)
    assert json.dumps(again, default=str) == json.dumps(rows[:len(lib.loops)], default=str)   # NaN reads as NaN
