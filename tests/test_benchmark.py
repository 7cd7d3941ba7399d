"""task=benchmark and the metrics' validity on the tiny corpus: GT scores itself perfectly,
FGD grows with noise and under block shuffling, beat consistency prefers the window's own audio,
failures are rows, a one-session corpus is a clear error."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from convsynth_jax.annotate.params import AnnotateParams
from convsynth_jax.errors import ConfigError
from convsynth_jax.evaluation import benchmark as bm
from convsynth_jax.evaluation.field import fgd, kinematic
from convsynth_jax.evaluation.field.params import FieldMetricParams
from convsynth_jax.evaluation.field.views import motion_view

FPS = 30.0
P = FieldMetricParams()


@pytest.fixture(scope="module")
def gt_views(tiny_annotations):
    """(cases, body views of their ground truth) of the tiny corpus: 15 s windows, 14 s hop."""
    cases = bm.benchmark_cases(tiny_annotations, FPS, 15.0, 14.0)
    gt, mm = bm.controls(tiny_annotations, cases, FPS, 15.0, 14.0)
    views = {c.key: motion_view(gt.motions[c.key][2], "body", P.joints, AnnotateParams()) for c in cases}
    return cases, views, gt, mm


def _raw(rel):
    return fgd.raw_window_features(rel, P.fgd.raw_window_frames, P.fgd.raw_frame_step)


def _shuffle_blocks(rel, block, rng):
    n = len(rel) // block
    order = rng.permutation(n)
    return np.concatenate([rel[k * block:(k + 1) * block] for k in order] + [rel[n * block:]])


def test_view_matches_root_relative_kernel(tiny_annotations):
    from convsynth_jax.kinematics import pose_features

    m = next(iter(next(iter(tiny_annotations.values())).values())).motion.slice(0, 60)
    v = motion_view(m, "body", P.joints, AnnotateParams())
    from convsynth_jax.evaluation.field.views import body_joints

    keep, _ = body_joints(m.skeleton.names, P.joints)
    np.testing.assert_allclose(v.relative, np.asarray(pose_features(m).positions, np.float64)[:, keep], atol=1e-3)


def test_ground_truth_scores_itself_perfectly_and_fgd_grows_with_noise_and_shuffling(gt_views):
    cases, views, _, _ = gt_views
    rel = [views[c.key].relative for c in cases]
    gt_feat = np.concatenate([_raw(r) for r in rel])
    assert fgd.fgd(gt_feat, gt_feat) == pytest.approx(0.0, abs=1e-6 * np.trace(np.cov(gt_feat.T)))
    h = kinematic.motion_histograms(views[cases[0].key].global_positions, FPS, P.histogram)
    assert kinematic.hellinger(h["speed"], h["speed"]) == pytest.approx(0.0, abs=1e-7)
    rng = np.random.default_rng(0)
    noisy = [fgd.fgd(gt_feat, np.concatenate([_raw(r + rng.normal(0, s, r.shape)) for r in rel]))
             for s in P.noise_levels]
    assert all(a < b for a, b in zip(noisy, noisy[1:])), noisy
    block = int(P.shuffle_block * FPS)
    shuffled = fgd.fgd(gt_feat, np.concatenate([_raw(_shuffle_blocks(r, block, rng)) for r in rel]))
    odd = [r for r, c in zip(rel, cases) if c.window % 2]
    even = [r for r, c in zip(rel, cases) if not c.window % 2]
    halves = fgd.fgd(np.concatenate([_raw(r) for r in odd]), np.concatenate([_raw(r) for r in even]))
    assert shuffled > 0.0 and noisy[0] > 0.0 and halves > 0.0


def test_beat_consistency_prefers_the_windows_own_audio(gt_views, tiny_annotations, librosa_ready):
    from convsynth_jax.evaluation.field import beat

    cases, views, gt, mm = gt_views
    own, other = [], []
    for c in cases:
        a = bm.case_audio(tiny_annotations, c, FPS)
        ab = beat.audio_beats(a, P.beat)
        for motion, out in ((gt.motions[c.key][2], own), (mm.motions[c.key][2], other)):
            v = motion_view(motion, "body", P.joints, AnnotateParams())
            out.append(beat.beat_consistency(beat.motion_beats(v.relative[:, list(v.upper)], FPS, P.beat), ab,
                                             c.num_frames / FPS, P.beat))
    assert np.nanmean(own) > np.nanmean(other)


def test_one_session_corpus_is_a_clear_error(tiny_annotations):
    one = dict(list(tiny_annotations.items())[:1])
    with pytest.raises(ConfigError, match="at least two sessions"):
        bm.benchmark_cases(one, FPS, 15.0, 14.0)


def test_failures_and_missing_windows_are_rows(tmp_path, tiny_annotations):
    """A sweep whose window failed, one whose BVH is missing, and a fold it never ran."""
    cases = bm.benchmark_cases(tiny_annotations, FPS, 15.0, 14.0, max_windows=1, folds=[0, 1])
    c0 = [c for c in cases if c.fold == 0]
    job = tmp_path / "sweep" / "0"
    (job / "bvh").mkdir(parents=True)
    pd.DataFrame([{"fold": 0, "condition": "none", "window": c.window, "role": c.role, "success": k == 0,
                   "status": "ok", "error": None if k == 0 else "ValueError: boom"}
                  for k, c in enumerate(c0)]).to_csv(job / "cases.csv", index=False)
    sm = bm.sweep_motions(tmp_path / "sweep", "broken", "none", cases, ("head",))
    status = {c.key: sm.motions[c.key][0] for c in cases}
    assert status[c0[0].key] == "missing" and "no BVH" in sm.motions[c0[0].key][1]
    assert status[c0[1].key] == "failed" and "boom" in sm.motions[c0[1].key][1]
    assert all(status[c.key] == "missing" for c in cases if c.fold == 1)
    gt, mm = bm.controls(tiny_annotations, cases, FPS, 15.0, 14.0)
    res = bm.score_benchmark(cases, [gt, mm, sm], {}, FPS, FieldMetricParams(bootstrap=20, bootstrap_set_level=5),
                             AnnotateParams(), {})
    rows = res.rows[res.rows["system"] == "broken"]
    assert len(rows) == len(cases) and set(rows["status"]) == {"missing", "failed"}
    assert rows["jerk"].isna().all()
    board = res.leaderboard
    g = board[(board["system"] == bm.GROUND_TRUTH) & (board["scope"] == "body")].set_index("metric")["value"]
    assert g["fgd_raw"] == pytest.approx(0.0, abs=1e-6) and g["hellinger_speed"] == 0.0
    assert g["cca_m"] == pytest.approx(1.0, abs=1e-6)


def test_benchmark_task_writes_leaderboard(tmp_path, tiny_corpus_dir, tiny_cache_dir, librosa_ready):
    """The task end to end on one window of one fold with random playback (the autoencoder, one
    epoch, trains on the tiny corpus itself here: a wiring test, not a valid FGD)."""
    import json

    from convsynth_jax.config import compose, run_task

    cfg = compose(["task=benchmark", "corpus=synthetic_tiny", f"corpus.root={tiny_corpus_dir}",
                   f"cache_dir={tiny_cache_dir('bench_cache')}", "progress=false", "loo.max_windows=1",
                   "task.folds=[0]", "task.only=random_playback", f"task.autoencoder_corpus={tiny_corpus_dir}",
                   "+task.metrics.autoencoder.epochs=1", "+task.metrics.autoencoder.window_frames=[30]",
                   "+task.metrics.bootstrap=10", "+task.metrics.bootstrap_set_level=3"])
    summary = run_task(cfg, tmp_path)
    for name in ("benchmark.csv", "leaderboard.csv", "leaderboard.md", "leaderboard.png", "summary.json"):
        assert (tmp_path / name).is_file(), name
    rows = pd.read_csv(tmp_path / "benchmark.csv")
    assert set(rows["system"]) == {bm.GROUND_TRUTH, bm.MISMATCHED, "random_playback"}
    assert set(rows["scope"]) == {"body", "head"} and len(rows) == 3 * 2 * 2
    board = pd.read_csv(tmp_path / "leaderboard.csv")
    assert {"fgd_raw", "fgd_ae30", "beat_consistency", "gac"} <= set(board["metric"])
    assert json.loads((tmp_path / "summary.json").read_text())["character_windows"] == summary["character_windows"] == 2


def test_a_null_system_label_is_left_out():
    from convsynth_jax.schema import build_params
    from convsynth_jax.tasks.benchmark import BenchmarkSettings

    systems = {"random_playback": {"system": "random_playback", "condition": "none"}, "motion_graph": None,
               "cdbn": {"system": "cdbn", "condition": "cdbn"}}   # as conf/task/benchmark.yaml gives them
    s = build_params(BenchmarkSettings, {"systems": systems}, "task")
    assert s.systems["motion_graph"] is None
    assert s.systems["cdbn"].system == "cdbn" and s.systems["random_playback"].condition == "none"


def test_set_metrics_compare_a_system_with_the_ground_truth_of_the_windows_it_scored(gt_views):
    """A system that replays the recordings of the windows it solved and fails the rest has no
    distance to the ground truth at all (scored against every window it would have one); the
    noise-floor row is the odd windows' distance to the even ones, computed here independently."""
    cases, views, gt, _ = gt_views
    solved = [c for c in cases if c.role == cases[0].role and c.window % 3 == 0]
    assert 0 < len(solved) < len(cases)
    subset = bm.SystemMotions("subset", ("body",),
                              {c.key: (gt.motions[c.key] if c in solved else ("failed", "unsolvable", None))
                               for c in cases})
    res = bm.score_benchmark(cases, [gt, subset], {}, FPS, FieldMetricParams(bootstrap=5, bootstrap_set_level=3),
                             AnnotateParams(), {})
    board = res.leaderboard.set_index(["system", "scope", "metric"])
    assert board.loc[("subset", "body", "fgd_raw"), "value"] == pytest.approx(0.0, abs=1e-6)
    assert board.loc[("subset", "body", "hellinger_speed_set"), "value"] == pytest.approx(0.0, abs=1e-7)
    assert board.loc[("subset", "body", "fgd_raw"), "n_windows"] == len(solved)
    all_feat = np.concatenate([_raw(views[c.key].relative) for c in cases])
    sub_feat = np.concatenate([_raw(views[c.key].relative) for c in solved])
    assert fgd.fgd(sub_feat, all_feat) > 1e-3   # what the old reference (every window) would have reported
    odd = np.concatenate([_raw(views[c.key].relative) for c in cases if c.window % 2])
    even = np.concatenate([_raw(views[c.key].relative) for c in cases if not c.window % 2])
    floor = board.loc[(bm.NOISE_FLOOR, "body", "fgd_raw")]
    assert floor["value"] == pytest.approx(fgd.fgd(odd, even), rel=1e-6) and floor["value"] > 0
    assert np.isnan(floor["rank"]) and floor["n_windows"] == sum(c.window % 2 for c in cases)
    assert (bm.NOISE_FLOOR, "body", "jerk") not in board.index   # no per-window metrics for two halves
    assert (bm.NOISE_FLOOR, "body", "cca_m_set") not in board.index
    from convsynth_jax.figures.benchmark import leaderboard_figure

    fig = leaderboard_figure(res.leaderboard)
    lines = [ln for ax in fig.axes for ln in ax.get_lines() if ln.get_label() == "GT odd vs even"]
    assert lines and all(bm.NOISE_FLOOR.replace("_", "\n") not in [t.get_text() for t in ax.get_xticklabels()]
                         for ax in fig.axes)
