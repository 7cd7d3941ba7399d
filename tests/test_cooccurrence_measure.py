"""One co-occurrence measure: Eq. 1 thresholds per recording everywhere (Table 1, chance
windows, leave-one-out ground truth and synthesized windows), the consistency of the leave-one-out
ground truth with Table 1, the chance-baseline fallback for continuous speech, Wilson intervals and
the paired per-window test."""
import dataclasses

import numpy as np
import pandas as pd
import pytest

from convsynth_jax.annotate.motion import (character_thresholds, idle_threshold, recording_thresholds,
                                           segment_motion)
from convsynth_jax.annotate.params import AnnotateParams
from convsynth_jax.config import default_params
from convsynth_jax.errors import ConfigError
from convsynth_jax.stats.cooccurrence import cooccurrence_table, hypothesis_matches
from convsynth_jax.stats.params import StatsParams
from convsynth_jax.stats.hypothesis import paired_rate_test, wilson_interval

AP = AnnotateParams()


# ------------------------------------------------------------------------------ thresholds (Eq. 1)
def test_recording_and_character_thresholds():
    rec = {"LH": np.array([2.0, 22.0, 5.0]), "Nod": np.array([0.0, 10.0])}
    th = recording_thresholds(rec, 0.1)
    assert th == {"LH": pytest.approx(4.0), "Nod": pytest.approx(1.0)}
    # synthesized motion: the mean over the character's training recordings, per kind
    assert character_thresholds([{"LH": 4.0, "Nod": 1.0}, {"LH": 6.0, "Nod": 3.0}]) == {"LH": 5.0, "Nod": 2.0}
    with pytest.raises(ConfigError, match="no training recordings"):
        character_thresholds([])


def test_segment_motion_and_hypothesis_matches_use_the_given_thresholds():
    """A small movement in a short array: over that array alone Eq. 1 calls it a nod; with the
    threshold of the recording it came from (which had large nods elsewhere) it is not one."""
    fps = 10.0
    v = np.zeros(60)
    v[20:26] = [0.1, 0.3, 0.5, 0.3, 0.1, 0.0]  # small head motion
    speeds = {"LH": np.zeros(60), "RH": np.zeros(60), "Nod": v}
    partner = pd.DataFrame({"kind": ["HP"], "start": [2.0], "end": [2.6]})
    own = pd.DataFrame({"kind": [], "start": [], "end": []})
    assert len(segment_motion(speeds, own, fps, partner, AP)) == 1            # thresholds over this array
    recording = {"LH": 1.0, "RH": 1.0, "Nod": idle_threshold(np.r_[v, 8.0], 0.1)}  # 0.8: a clip with a big nod
    assert segment_motion(speeds, own, fps, partner, AP, thresholds=recording).empty
    hit, _ = hypothesis_matches(speeds, own, partner, fps, "PH-Nod", thresholds=recording)
    assert hit.tolist() == [False]
    hit, _ = hypothesis_matches(speeds, own, partner, fps, "PH-Nod", thresholds=recording_thresholds(speeds))
    assert hit.tolist() == [True]
    with pytest.raises(ConfigError, match="Nod"):
        hypothesis_matches(speeds, own, partner, fps, "PH-Nod", thresholds={"LH": 1.0})
    with pytest.raises(TypeError):  # no silent default: thresholds must be given
        hypothesis_matches(speeds, own, partner, fps, "PH-Nod")


# ------------------------------------------------------------------------------ intervals and tests
def test_wilson_interval_against_the_formula():
    lo, hi = wilson_interval(25, 82)
    p, n, z = 25 / 82, 82, 1.959963984540054
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    assert (lo, hi) == (pytest.approx(centre - half), pytest.approx(centre + half))
    assert wilson_interval(0, 10)[0] == pytest.approx(0.0) and wilson_interval(10, 10)[1] == pytest.approx(1.0)
    assert all(np.isnan(wilson_interval(0, 0)))


def test_wilson_interval_ends_are_exact():
    # statsmodels gives 5.6e-17 for the lower bound of 0/10: a report then prints "5.6e-17", not 0.
    assert wilson_interval(0, 10)[0] == 0.0 and wilson_interval(0, 87)[0] == 0.0
    assert wilson_interval(10, 10)[1] == 1.0 and wilson_interval(87, 87)[1] == 1.0
    assert 0.0 < wilson_interval(1, 10)[0] < wilson_interval(1, 10)[1] < 1.0


def test_paired_rate_test():
    a = np.array([1.0, 1.0, 0.5, 1.0, 1.0, 1.0, 0.5, 1.0, 1.0, 1.0])
    b = np.array([0.0, 0.5, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0, 0.5, 0.5])
    from scipy.stats import wilcoxon

    stat, p, n = paired_rate_test(a, b)
    assert n == 10 and p == pytest.approx(wilcoxon(a, b).pvalue) and p < 0.01
    assert paired_rate_test(a, a) == (0.0, 1.0, 10)
    assert paired_rate_test([np.nan, 1.0], [0.0, 1.0])[2] == 1


def test_cooccurrence_by_condition_has_intervals_and_the_paired_test():
    from convsynth_jax.evaluation.summaries import cooccurrence_by_condition

    rows = []
    for w in range(12):
        r = {"system": "s", "condition": "all", "character": "f", "success": True}
        for h in ("PC-LH", "PC-RH", "PC-LH/RH", "LR-Nod", "PH-Nod"):
            r.update({f"gt_{h}_matched": 2, f"gt_{h}_total": 2, f"synth_{h}_matched": w % 2, f"synth_{h}_total": 2})
        rows.append(r)
    co = cooccurrence_by_condition(pd.DataFrame(rows))
    assert {"ci_low", "ci_high", "gt_ci_low", "gt_ci_high", "p_value", "n_pairs", "p_wilcoxon"} <= set(co)
    r = co.iloc[0]
    assert r.synth_matched == 6 and r.synth_total == 24 and (r.ci_low, r.ci_high) == wilson_interval(6, 24)
    assert r.n_pairs == 12 and r.p_wilcoxon < 0.01 and r.gt_ci_high == pytest.approx(1.0)


# ------------------------------------------------------------------------------ chance baseline
@pytest.fixture(scope="module")
def annotations(tiny_annotations):
    import copy

    return copy.deepcopy(tiny_annotations)   # annotated once per session with the default parameters (AP)


def _continuous_speech(annotations):
    """Every participant's own PC segments replaced by back-to-back 2 s clauses over the whole clip
    (a fluent speaker with no pause): no random window fits away from them."""
    out = []
    for parts in annotations.values():
        for a in parts.values():
            dur = a.motion.num_frames / a.motion.fps
            starts = np.arange(0.0, dur - 2.0, 2.0)
            segs = pd.DataFrame({"kind": "PC", "start": starts, "peak": starts + 1.0, "end": starts + 2.0,
                                 "text": "words"})
            out.append(dataclasses.replace(a, segments=segs))
    return out


def test_continuous_speech_falls_back_to_shifted_windows(annotations, caplog):
    """The old code showed chance 0/0 with chi2 = 0 and p = 1 here, silently."""
    speech = _continuous_speech(annotations)
    t = cooccurrence_table(speech, AP, StatsParams(n_permutations=200))
    pc = t[t["hypothesis"].str.startswith("PC")]
    assert (pc["chance_method"] == "shifted").all(), pc
    assert (pc["chance_total"] == pc["total"]).all() and (pc["chance_total"] > 0).all()
    assert pc["p_chi2"].between(0, 1).all() and pc["chance_rate"].notna().all()
    # rows whose channel still has pauses (the partner's hesitations, left as they were) keep the away baseline
    assert (t.loc[t["hypothesis"] == "PH-Nod", "chance_method"] == "away").all()
    with caplog.at_level("WARNING"):
        none = cooccurrence_table(speech, AP, StatsParams(n_permutations=200, chance_fallback="none"))
    pcn = none[none["hypothesis"].str.startswith("PC")]
    assert (pcn["chance_method"] == "none").all() and (pcn["chance_total"] == 0).all()
    assert pcn[["p_chi2", "p_permutation", "chi2", "chance_rate"]].isna().all().all()
    assert "no chance baseline" in caplog.text
    with pytest.raises(ConfigError, match="chance_fallback"):
        StatsParams(chance_fallback="nearest")
    with pytest.raises(ConfigError, match="stats.chance_baseline"):
        default_params(["stats.chance_baseline=elsewhere"])


def test_table1_has_interval_and_baseline_columns(annotations):
    t = cooccurrence_table(annotations, AP, StatsParams(n_permutations=200))
    assert (t["chance_method"] == "away").all()  # the tiny corpus has pauses: today's baseline everywhere
    for r in t.itertuples():
        assert (r.ci_low, r.ci_high) == wilson_interval(r.matched, r.total)
        assert r.ci_low <= r.rate <= r.ci_high
        assert (r.chance_ci_low, r.chance_ci_high) == wilson_interval(r.chance_matched, r.chance_total)


# ------------------------------------------------------------------------------ leave-one-out
@pytest.fixture(scope="module")
def tiny_params(tiny_corpus_dir):
    return default_params(["corpus=synthetic_tiny", f"corpus.root={tiny_corpus_dir}", "progress=false",
                           "stats.n_permutations=200", "system=random_playback"])


def test_loo_ground_truth_reproduces_table1(annotations, tiny_params):
    """The consistency check on the tiny corpus: the ground truth of every leave-one-out
    window of every fold, counted as run_fold counts it, sums to Table 1 within what cutting the
    recordings into windows explains, and its rate lies in Table 1's 95% Wilson interval. With Eq. 1
    over each window (the old code path) the check fails."""
    from convsynth_jax.evaluation.consistency import check_consistency

    ok = check_consistency(annotations, tiny_params)
    assert ok["passes"].all(), ok
    assert (ok["loo_total"] - ok["table1_total"] == ok["duplicated"] - ok["uncovered"]).all()
    old = check_consistency(annotations, tiny_params, threshold_scope="window")
    assert not old["passes"].all(), old
    # the old path over-counts nods in quiet windows: more matches than Table 1, never fewer
    assert (old["loo_matched"] >= ok["loo_matched"]).sum() >= 8


def test_run_fold_ground_truth_matches_the_consistency_path(annotations, tiny_params):
    """run_fold's gt_* columns (random playback, every fold) are the counts the consistency check
    sums, so the leave-one-out tables themselves reproduce Table 1."""
    from convsynth_jax.evaluation.consistency import consistency_table, loo_ground_truth
    from convsynth_jax.evaluation.loo import run_fold
    from convsynth_jax.systems.base import make_system

    system = make_system(tiny_params, tiny_params.system)
    cases = pd.concat([run_fold(system, annotations, f, "none", tiny_params) for f in range(len(annotations))])
    gt = loo_ground_truth(annotations, tiny_params)
    table1 = cooccurrence_table(annotations, AP, tiny_params.stats)
    via_cases = consistency_table(table1, cases, gt)
    assert via_cases["passes"].all(), via_cases
    windows = gt[gt["window"] >= 0].sort_values(["fold", "window", "role"]).reset_index(drop=True)
    cases = cases.sort_values(["fold", "window", "role"]).reset_index(drop=True)
    cols = [c for c in windows if c.startswith("gt_")]
    assert (windows[cols].to_numpy() == cases[cols].to_numpy()).all()
    # every system is scored by this measure: synthesized hand and nod counts are present
    assert cases["synth_PH-Nod_total"].notna().all() and cases["synth_PC-LH_total"].notna().all()


def _quieten(motion, f0: int, f1: int, keep: float = 0.05):
    """Frames [f0, f1) of ``motion`` pulled 95% of the way to the pose of frame f0 (rotations as
    normalized lerps of sign-aligned quaternions): the same movements at 5% of their amplitude."""
    rot = np.array(motion.rotations, dtype=np.float64, copy=True)
    ref = rot[f0].copy()
    seg = rot[f0:f1]
    sign = np.where(np.sum(seg * ref, axis=-1, keepdims=True) < 0, -1.0, 1.0)
    q = ref + keep * (sign * seg - ref)
    rot[f0:f1] = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return dataclasses.replace(motion, rotations=rot.astype(np.asarray(motion.rotations).dtype))


def test_quiet_window_ground_truth_uses_the_recording_threshold(annotations, tiny_params):
    """Small head motion in a quiet window is not a nod. One leave-one-out window of one recording
    (the one with the most nods) is made quiet: its movements at 5% amplitude; the rest of the
    recording keeps its nods. Judged by the recording's Eq. 1 threshold the window holds no nod and
    no gesture; the old code, with Eq. 1 over the 15 s window, still found nods there."""
    from convsynth_jax.evaluation.consistency import loo_ground_truth
    from convsynth_jax.evaluation.loo import run_fold
    from convsynth_jax.systems.base import make_system

    fps = 30.0
    before = loo_ground_truth(annotations, tiny_params)
    before = before[before["window"] >= 0]
    pick = before.assign(nods=before["gt_PH-Nod_matched"] + before["gt_LR-Nod_matched"]).sort_values(
        "nods", kind="stable").iloc[-1]
    fold, window, role = int(pick["fold"]), int(pick["window"]), pick["role"]
    assert pick["nods"] >= 2  # nods were there
    session = list(annotations)[fold]
    f0 = int(round(window * tiny_params.loo.hop * fps))
    f1 = f0 + int(round(tiny_params.loo.window * fps))
    quiet = {s: dict(d) for s, d in annotations.items()}
    a = annotations[session][role]
    quiet[session][role] = dataclasses.replace(a, motion=_quieten(a.motion, f0, f1))
    p = dataclasses.replace(tiny_params, loo=dataclasses.replace(tiny_params.loo, max_windows=window + 1))
    cases = run_fold(make_system(p, p.system), quiet, fold, "none", p)
    row = cases[(cases["role"] == role) & (cases["window"] == window)].iloc[0]
    for h in ("PC-LH", "PC-RH", "PC-LH/RH", "LR-Nod", "PH-Nod"):
        assert row[f"gt_{h}_total"] == pick[f"gt_{h}_total"]
        assert row[f"gt_{h}_matched"] == 0, (h, row[f"gt_{h}_matched"])
    # the window-relative threshold (the old code path) still finds the scaled-down nods
    old = loo_ground_truth(quiet, p, threshold_scope="window")
    old = old[(old["fold"] == fold) & (old["window"] == window) & (old["role"] == role)].iloc[0]
    assert old["gt_PH-Nod_matched"] + old["gt_LR-Nod_matched"] >= 1


class _CopySystem:
    """A stand-in system that 'synthesizes' the held-out ground truth itself (hands or not)."""

    def __new__(cls, params, annotations, produces_hands=True):
        from convsynth_jax.systems.base import SynthesisSystem, SystemParams, WindowResult

        class Copy(SynthesisSystem):
            def fit(self, clips, character, condition, cache_dir=None):
                return None

            def synthesize(self, model, window, condition):
                ann = annotations[window.session][window.role]
                return WindowResult(True, ann.motion.slice(window.start_frame, window.start_frame + window.num_frames))

        s = Copy(params, SystemParams("copy", "x:y", {"none": {}}))
        s.produces_hands = produces_hands
        return s


def test_synthesized_and_ground_truth_windows_are_counted_alike(annotations, tiny_params):
    """Every system goes through one measure: motion equal to the ground truth, judged with the
    same thresholds, gets the ground truth's counts; with the character's mean thresholds (what a
    synthesized window gets) the counts may differ only by that threshold; a system without hands
    reports hand hypotheses as NaN, not 0."""
    from convsynth_jax.evaluation.loo import evaluate_window, fold_thresholds, session_windows, window_input

    session = list(annotations)[0]
    held = annotations[session]
    gt_th, synth_th = fold_thresholds(annotations, session, AP)
    assert set(gt_th) == set(held) and set(synth_th) == {"female", "male"}
    # the held-out recording's own threshold is not the training mean: the two really differ
    role = list(held)[0]
    assert gt_th[role] != synth_th[held[role].character]
    w = session_windows(held, 30.0, 15.0, 14.0)[0]
    win = window_input(held, role, w, 30.0, 0)
    gt = held[role].motion.slice(win.start_frame, win.start_frame + win.num_frames)
    system = _CopySystem(tiny_params, annotations)
    row, motion = evaluate_window(system, None, win, "none", gt, tiny_params, gt_thresholds=gt_th[role],
                                  synth_thresholds=gt_th[role])
    hyps = ("PC-LH", "PC-RH", "PC-LH/RH", "LR-Nod", "PH-Nod")
    for h in hyps:
        assert (row[f"synth_{h}_matched"], row[f"synth_{h}_total"]) == (row[f"gt_{h}_matched"], row[f"gt_{h}_total"])
    with pytest.raises(TypeError):  # thresholds are required
        evaluate_window(system, None, win, "none", gt, tiny_params)
    headless = _CopySystem(tiny_params, annotations, produces_hands=False)
    row2, _ = evaluate_window(headless, None, win, "none", gt, tiny_params, gt_thresholds=gt_th[role],
                              synth_thresholds=synth_th[held[role].character])
    for h in hyps[:3]:
        assert np.isnan(row2[f"synth_{h}_matched"]) and np.isnan(row2[f"synth_{h}_total"])
        assert row2[f"gt_{h}_total"] == row[f"gt_{h}_total"]  # the ground truth keeps its hands
    for h in hyps[3:]:
        assert row2[f"synth_{h}_total"] == row[f"gt_{h}_total"]


def test_figures_draw_wilson_error_bars():
    from convsynth_jax.figures.motion_graph import ablation_figure, table1_figure

    t = pd.DataFrame({"character": ["f", "f"], "hypothesis": ["PC-LH", "LR-Nod"], "rate": [0.5, 0.25],
                      "ci_low": [0.4, 0.1], "ci_high": [0.6, 0.45], "chance_method": ["away", "none"],
                      "chance_rate": [0.1, np.nan], "chance_ci_low": [0.05, np.nan], "chance_ci_high": [0.2, np.nan]})
    ax = table1_figure(t).axes[0]
    bars = [c for c in ax.containers if getattr(c, "errorbar", None) is not None]
    assert len(bars) == 2
    seg = bars[0].errorbar.lines[2][0].get_segments()
    assert [tuple(np.round(s[:, 1], 6)) for s in seg] == [(40.0, 60.0), (10.0, 45.0)]
    assert "LR-Nod\n(none)" in [x.get_text() for x in ax.get_xticklabels()]
    co = pd.DataFrame({"condition": ["all", "all"], "character": ["f", "f"], "hypothesis": ["PC-LH", "LR-Nod"],
                       "synth_rate": [0.5, 0.3], "ci_low": [0.45, 0.2], "ci_high": [0.55, 0.4],
                       "gt_rate": [0.6, 0.7], "gt_ci_low": [0.5, 0.6], "gt_ci_high": [0.7, 0.8]})
    ax = ablation_figure(co).axes[0]
    bars = [c for c in ax.containers if getattr(c, "errorbar", None) is not None]
    segs = [tuple(np.round(s[:, 1], 6)) for c in bars for s in c.errorbar.lines[2][0].get_segments()]
    assert segs == [(50.0, 70.0), (60.0, 80.0), (45.0, 55.0), (20.0, 40.0)]


def test_head_only_system_is_measured_on_the_head(annotations, tiny_params):
    """A head-only system (no hands) animates the head on a still body: its quality metrics are
    computed on the head point (in the ground truth too), not on every joint, where a still body
    scored zero jerk and acceleration whatever the head did (the CDBN rows of a sweep)."""
    from convsynth_jax.evaluation.loo import evaluate_window, fold_thresholds, session_windows, window_input
    from convsynth_jax.skeleton import Motion
    from convsynth_jax.systems.base import SynthesisSystem, SystemParams, WindowResult

    session = list(annotations)[0]
    held = annotations[session]
    role = list(held)[0]
    gt_th, synth_th = fold_thresholds(annotations, session, AP)
    w = session_windows(held, 30.0, 15.0, 14.0)[0]
    win = window_input(held, role, w, 30.0, 0)
    gt = held[role].motion.slice(win.start_frame, win.start_frame + win.num_frames)
    head = gt.skeleton.names.index("Head")

    class StillBodyMovingHead(SynthesisSystem):
        produces_hands = False

        def fit(self, clips, character, condition, cache_dir=None):
            return None

        def synthesize(self, model, window, condition):
            rot = np.broadcast_to(np.asarray(gt.rotations[:1], np.float64), gt.rotations.shape).copy()
            rot[:, head] = np.asarray(gt.rotations[:, head])  # only the head moves, as the ground truth's
            trans = np.broadcast_to(np.asarray(gt.translations[:1]), gt.translations.shape).copy()
            return WindowResult(True, Motion(gt.skeleton, rot, trans, gt.fps, "head"))

    system = StillBodyMovingHead(tiny_params, SystemParams("head", "x:y", {"none": {}}))
    row, _ = evaluate_window(system, None, win, "none", gt, tiny_params, gt_thresholds=gt_th[role],
                             synth_thresholds=synth_th[held[role].character])
    assert row["metric_scope"] == "head"
    assert row["jerk"] > 0 and row["acceleration"] > 0 and row["max_jump"] > 0
    assert row["gt_jerk"] > 0


def test_head_only_diversity_is_measured_on_the_head(tiny_params, annotations):
    """Window diversity of a head-only system compares its head motion between windows; over every
    joint of a still body it was 0 whatever the head did."""
    from convsynth_jax.evaluation.loo import run_fold
    from convsynth_jax.skeleton import Motion
    from convsynth_jax.systems.base import SynthesisSystem, SystemParams, WindowResult

    class StillBodyMovingHead(SynthesisSystem):
        produces_hands = False

        def fit(self, clips, character, condition, cache_dir=None):
            return None

        def synthesize(self, model, window, condition):
            ann = annotations[window.session][window.role]
            gt = ann.motion.slice(window.start_frame, window.start_frame + window.num_frames)
            head = gt.skeleton.names.index("Head")
            rot = np.broadcast_to(np.asarray(ann.motion.rotations[:1], np.float64), gt.rotations.shape).copy()
            rot[:, head] = np.asarray(gt.rotations[:, head])
            trans = np.broadcast_to(np.asarray(ann.motion.translations[:1]), gt.translations.shape).copy()
            return WindowResult(True, Motion(gt.skeleton, rot, trans, gt.fps, "head"))

    system = StillBodyMovingHead(tiny_params, SystemParams("head", "x:y", {"none": {}}))
    rows = run_fold(system, annotations, 0, "none", tiny_params)
    assert (rows["metric_scope"] == "head").all()
    assert (rows["diversity"] > 0).all(), rows["diversity"].tolist()
