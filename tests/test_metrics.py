import numpy as np
import pandas as pd
import pytest

from convsynth_jax.evaluation import metrics, summaries
from convsynth_jax.evaluation.windows import sliding_windows, window_segments


def test_derivative_metrics_by_hand():
    t = np.arange(30)[:, None, None] / 30.0
    line = np.concatenate([t * 10.0, 0 * t, 0 * t], axis=-1)          # 10 units/s, 1 joint
    assert metrics.mean_acceleration(line, 30.0) == pytest.approx(0.0, abs=1e-9)
    parab = np.concatenate([0.5 * 4.0 * t ** 2, 0 * t, 0 * t], axis=-1)  # acceleration 4 units/s^2
    assert metrics.mean_acceleration(parab, 30.0) == pytest.approx(4.0, rel=1e-6)
    assert metrics.mean_jerk(parab, 30.0) == pytest.approx(0.0, abs=1e-6)
    assert metrics.max_frame_jump(line).max() == pytest.approx(10.0 / 30.0)


def test_hellinger_and_speed_histograms():
    assert metrics.hellinger_distance([1, 2, 3], [2, 4, 6]) == pytest.approx(0.0)
    assert metrics.hellinger_distance([1, 0], [0, 1]) == pytest.approx(1.0)
    rng = np.random.default_rng(0)
    a = np.cumsum(rng.normal(0, 1, (200, 3, 3)), axis=0)
    assert metrics.speed_histogram_distance(a, a, 30.0) == pytest.approx(0.0)
    assert metrics.speed_histogram_distance(a, 5 * a, 30.0) > 0.3


def test_window_diversity():
    w = np.ones((10, 2, 3))
    assert metrics.window_diversity([w, w.copy()]) == pytest.approx(0.0)
    assert metrics.window_diversity([w, w + np.array([3.0, 4.0, 0.0])]) == pytest.approx(5.0)
    assert np.isnan(metrics.window_diversity([w]))


def test_sliding_windows_and_segments():
    ws = sliding_windows(106.0, 15.0, 14.0)
    assert [w.start for w in ws] == [0, 14, 28, 42, 56, 70, 84] and ws[-1].end == 99
    seg = pd.DataFrame({"kind": ["PC", "LR", "PC"], "start": [13.0, 20.0, 40.0], "peak": [14.5, 20.2, 40.5],
                        "end": [15.5, 20.5, 41.0], "text": ["a", "b", "c"]})
    out = window_segments(seg, ws[1])
    assert out["kind"].tolist() == ["PC", "LR"]
    assert out["start"].tolist() == [-1.0, 6.0]  # crossing segments keep their true times


def test_summaries_success_and_timing():
    cases = pd.DataFrame({"fold": [0, 0, 0, 0], "session": ["s"] * 4, "condition": ["all", "all", "none", "none"],
                          "window": [0, 0, 0, 0], "character": ["f", "m", "f", "m"], "success": [True, False, True, True],
                          "system": "motion_graph", "fit_seconds": [10.0, 12.0, 10.0, 12.0],
                          "synthesis_seconds": [0.1, 0.2, 0.3, 0.4], "fit_procedure": "fit (graph construction)",
                          "synthesis_procedure": "synthesis (search)"})
    r = summaries.success_rates(cases).set_index("condition")
    assert r.loc["all", "success_rate"] == 0.0 and r.loc["none", "success_rate"] == 1.0
    assert r.loc["all", "success_rate_f"] == 1.0
    t = summaries.timing_table(cases).set_index("procedure")
    assert t.loc["fit (graph construction)", "mean_s"] == 11.0 and t.loc["synthesis (search)", "n"] == 4
    md = summaries.to_markdown(t.reset_index())
    assert md.count("\n") == 4 and "| synthesis (search) |" in md
    assert "\\bottomrule" in summaries.to_latex(t.reset_index())
    # the names come from the rows (the system), not from the system's name
    other = cases.assign(system="my_system").drop(columns=["fit_procedure", "synthesis_procedure"])
    assert summaries.timing_table(other)["procedure"].tolist() == ["fit", "synthesis"]
    named = other.assign(fit_procedure="training", synthesis_procedure="sampling")
    assert summaries.timing_table(named)["procedure"].tolist() == ["training", "sampling"]


def _slow_seam_ratio(pos, gt, fps, synthetic_at, radius=3):
    """The obvious version: loop over frames and joints."""
    def acc(p, u, j):  # central second difference at frame u, relative to joint 0
        r = [np.asarray(p[v, j], float) - np.asarray(p[v, 0], float) for v in (u - 1, u, u + 1)]
        return float(np.sqrt(sum(((r[2][k] - 2 * r[1][k] + r[0][k]) * fps * fps) ** 2 for k in range(3))))

    F, J = pos.shape[:2]
    gmax = max(acc(gt, u, j) for u in range(1, len(gt) - 1) for j in range(J))
    best = None
    for t in synthetic_at:
        for u in range(t - radius, t + radius + 1):
            if 1 <= u <= F - 2:
                for j in range(J):
                    a = acc(pos, u, j)
                    best = a if best is None else max(best, a)
    return float("nan") if best is None else best / gmax


def test_seam_ratio_equals_the_slow_loop():
    from convsynth_jax.evaluation.metrics import seam_ratio

    rng = np.random.default_rng(3)
    pos = np.cumsum(rng.normal(0, 1, (30, 5, 3)), axis=0)
    gt = np.cumsum(rng.normal(0, 1, (30, 5, 3)), axis=0)
    pos[17:, 3] += 8.0  # a pop near the transition at 16
    for at in ([16], [0, 29], [2, 3, 27], [10, 11]):
        assert seam_ratio(pos, gt, 30.0, at) == pytest.approx(_slow_seam_ratio(pos, gt, 30.0, at), rel=1e-12)
    assert np.isnan(seam_ratio(pos, gt, 30.0, []))
    # the pop dominates: a seam around frame 16 is sharper than anything in the ground truth
    assert seam_ratio(pos, gt, 30.0, [16]) > 1.0


def test_seam_content_ratio_equals_the_slow_loop():
    """The source content at the seams (new source frames and, during each blend, the previous clip's
    continuation), against a loop over frames, joints and transitions with the clips' own accelerations."""
    from convsynth_jax.evaluation.metrics import clip_acceleration, seam_content_ratio

    rng = np.random.default_rng(5)
    fps = 30.0
    clips = {n: np.cumsum(rng.normal(0, 1, (40, 4, 3)), axis=0) for n in ("a", "b", "c")}
    clips["c"][20:, 2] += 50.0   # a fast burst in clip c around its frame 20 (its own content, no seam)
    gt = np.cumsum(rng.normal(0, 1, (24, 4, 3)), axis=0)
    # a path: a 0..9, b 5..11 (transition at 10), c 18..22 (transition at 17), a 30.. (transition at 22)
    src = ["a"] * 10 + ["b"] * 7 + ["c"] * 5 + ["a"] * 2
    frm = list(range(10)) + list(range(5, 12)) + list(range(18, 23)) + [30, 31]
    syn, blend = [10, 17, 22], 4
    acc = {n: clip_acceleration(p, fps) for n, p in clips.items()}

    def own_acc(n, f):   # clip n's acceleration at frame f (central difference), every joint, by hand
        p = clips[n]
        f = min(max(f, 1), len(p) - 2)
        r = [p[f + d] - p[f + d][0] for d in (-1, 0, 1)]
        return float(np.linalg.norm((r[2] - 2 * r[1] + r[0]) * fps * fps, axis=-1).max())

    want = 0.0
    for u in range(len(src)):
        if any(abs(u - t) <= 3 for t in syn):
            want = max(want, own_acc(src[u], frm[u]))
            for t in syn:
                if t <= u < t + blend:
                    want = max(want, own_acc(src[t - 1], min(frm[t - 1] + u - t + 1, 39)))
    gmax = max(float(np.linalg.norm(((gt[u + 1] - gt[u + 1][0]) - 2 * (gt[u] - gt[u][0]) + (gt[u - 1] - gt[u - 1][0]))
                                    * fps * fps, axis=-1).max()) for u in range(1, 23))
    got = seam_content_ratio(acc, src, frm, gt, fps, syn, blend)
    assert got == pytest.approx(want / gmax, rel=1e-12)
    # the burst in c is played next to the transition at 17: the content alone is over the ground truth
    assert got > 1.0
    assert np.isnan(seam_content_ratio(acc, src, frm, gt, fps, [], blend))
    # a burst in clip b just after the frames played (5..11): only the previous clip's continuation
    # during the blend after the transition at 17 (b frames 12..15) reaches it
    clips["b"][13:, 1] += 80.0
    acc["b"] = clip_acceleration(clips["b"], fps)
    with_cont = seam_content_ratio(acc, src, frm, gt, fps, syn, blend)
    assert with_cont > seam_content_ratio(acc, src, frm, gt, fps, syn, 0) + 1.0
    assert with_cont == pytest.approx(own_acc("b", 12) / gmax, rel=1e-12)


def test_every_jerk_is_the_one_definition():
    """Jerk has one home (``kinematics.jerk``): GENEA's average jerk, the leave-one-out's mean jerk and the
    CDBN's angular jerk (the key-point rate's target) give its mean norm."""
    from convsynth_jax.evaluation.field.kinematic import average_jerk
    from convsynth_jax.evaluation.metrics import mean_jerk
    from convsynth_jax.kinematics import jerk
    from convsynth_jax.systems.cdbn import _angular_jerk

    rng = np.random.default_rng(0)
    p = np.cumsum(rng.normal(size=(40, 5, 3)), axis=0)
    want = np.linalg.norm(np.diff(p, n=3, axis=0), axis=-1).mean() * 30.0 ** 3
    assert np.isclose(np.linalg.norm(jerk(p, 30.0), axis=-1).mean(), want, rtol=1e-12)
    assert np.isclose(average_jerk(p, 30.0), want, rtol=1e-12) and np.isclose(mean_jerk(p, 30.0), want, rtol=1e-12)
    a = p[:, 0]
    assert np.isclose(_angular_jerk(a, 30.0), np.linalg.norm(np.diff(a, n=3, axis=0), axis=1).mean() * 30.0 ** 3,
                      rtol=1e-12)
    assert _angular_jerk(a[:3], 30.0) == 0.0
