"""The figure contract: one figures/ package (per-system subpackages) and one save helper."""
from pathlib import Path

import numpy as np
import pytest
from matplotlib.figure import Figure

from convsynth_jax.figures import save_figure

PKG = Path(__file__).resolve().parent.parent / "convsynth_jax"


def _figure():
    fig = Figure(figsize=(2, 2))
    fig.subplots().plot([0, 1], [0, 1])
    return fig


@pytest.mark.parametrize("suffix, magic", [(".png", b"\x89PNG"), (".pdf", b"%PDF"), (".svg", b"<?xml")])
def test_save_figure_writes_the_format_its_suffix_names(tmp_path, suffix, magic):
    out = save_figure(_figure(), tmp_path / "sub" / f"f{suffix}")
    assert out == tmp_path / "sub" / f"f{suffix}" and out.read_bytes().startswith(magic)
    assert [p.name for p in out.parent.iterdir()] == [out.name]     # no temporary file left


def test_failed_save_leaves_nothing(tmp_path):
    class Broken(Figure):
        def savefig(self, *a, **k):
            Path(a[0]).write_bytes(b"half")
            raise RuntimeError("disk full")

    with pytest.raises(RuntimeError):
        save_figure(Broken(), tmp_path / "f.png")
    assert list(tmp_path.iterdir()) == []


def test_only_the_save_helper_writes_figures():
    writers = [str(p.relative_to(PKG)) for p in PKG.rglob("*.py") if "savefig(" in p.read_text()]
    assert writers == ["utils.py"]
    assert not (PKG / "cdbn" / "figures.py").exists() and not (PKG / "walktalk" / "figures.py").exists()


def test_panel_row_and_label_panel():
    from convsynth_jax.figures.panels import label_panel, panel_row

    fig, axes = panel_row(3, 2.0, 1.5)
    assert len(axes) == 3 and tuple(fig.get_size_inches()) == (6.0, 1.5)
    assert len(panel_row(0, 2.0, 1.5)[1]) == 1                      # an empty table still gets a panel
    axes[0].plot([0, 1], [0, 1], label="a")
    label_panel(axes[0], "t", "y", "x")
    label_panel(axes[1], "u", "v")
    assert (axes[0].get_title(), axes[0].get_xlabel(), axes[0].get_ylabel()) == ("t", "x", "y")
    assert (axes[1].get_title(), axes[1].get_xlabel(), axes[1].get_ylabel()) == ("u", "", "v")
    assert axes[0].get_legend().get_texts()[0].get_fontsize() == 7


def test_condition_bars_place_truth_then_each_condition_per_hypothesis():
    import pandas as pd

    from convsynth_jax.figures.motion_graph.bars import condition_bars

    g = pd.DataFrame({"hypothesis": ["LR", "PC", "LR", "PC"], "condition": ["all", "all", "none", "none"],
                      "gt_rate": [0.5, 0.3, 0.5, 0.3], "synth_rate": [0.1, 0.2, 0.3, 0.4]})
    b = condition_bars(g)
    assert b.hypotheses == ["LR", "PC"] and b.width == pytest.approx(0.8 / 3)
    np.testing.assert_allclose(b.truth_x, [-0.4 + 0.4 / 3, 0.6 + 0.4 / 3])
    assert [c for c, _, _ in b.conditions] == ["all", "none"]
    np.testing.assert_allclose(b.conditions[1][2], b.truth_x + 2 * b.width)     # side by side
    assert list(b.conditions[1][1]["synth_rate"]) == [0.3, 0.4] and list(b.truth["gt_rate"]) == [0.5, 0.3]


def test_cdbn_figures_plot_the_given_data():
    """Each figure draws exactly the numbers it is given: the scatter and the state ellipses (centre,
    axes from the covariance's eigenvalues), the CCA_m and LLR curves per number of states, and the
    original and synthesized trajectories in degrees against time."""
    from convsynth_jax.figures.cdbn import init_ellipses_figure, states_curve_figure, trajectories_figure

    rng = np.random.default_rng(0)
    data = rng.normal(size=(50, 3))
    comp = {k: {"motion_means": rng.normal(size=(2, 3)), "motion_covariances": np.stack([np.diag([4.0, 1.0, 1.0])] * 2)}
            for k in ("random", "lbg")}
    fig = init_ellipses_figure(data, comp)
    assert isinstance(fig, Figure) and len(fig.axes) == 2
    for ax, init in zip(fig.axes, ("random", "lbg")):
        np.testing.assert_allclose(ax.collections[0].get_offsets(), data[:, :2])
        centres = [e.center for e in ax.patches]
        np.testing.assert_allclose(centres, comp[init]["motion_means"][:, :2])
        assert all(sorted((e.width, e.height)) == [2.0, 4.0] for e in ax.patches)   # 2 sd along each axis
        assert ax.get_title().endswith(f"{init} initialization, 2 states")

    curves = {"jdbn": {5: {"cca_m": 0.3, "llr": 1.5}, 3: {"cca_m": 0.2, "llr": 1.0}},
              "cdbn": {2: {"cca_m": 0.4, "llr": 2.0}, 4: {"cca_m": 0.1, "llr": 2.5}}}
    fig = states_curve_figure(curves)
    by_title = {ax.get_title(): ax for ax in fig.axes if ax.get_title()}
    assert sorted(by_title) == ["cdbn", "jdbn"]
    for kind, ax in by_title.items():
        ns = sorted(curves[kind])
        (cca,) = ax.get_lines()
        (llr,) = [a for a in fig.axes if a is not ax and a.bbox.bounds == ax.bbox.bounds][0].get_lines()
        assert list(cca.get_xdata()) == ns and list(llr.get_xdata()) == ns
        assert list(cca.get_ydata()) == [curves[kind][n]["cca_m"] for n in ns]
        assert list(llr.get_ydata()) == [curves[kind][n]["llr"] for n in ns]

    original, synth = rng.normal(size=(20, 3)), rng.normal(size=(20, 3))
    fig = trajectories_figure(10.0, original, {"CDBN": synth}, np.r_[np.zeros(10), np.ones(10)].astype(int), ("other", "nod"))
    assert len(fig.axes) == 3
    for i, ax in enumerate(fig.axes):
        orig_line, synth_line = ax.get_lines()
        np.testing.assert_allclose(orig_line.get_xdata(), np.arange(20) / 10.0)
        np.testing.assert_allclose(orig_line.get_ydata(), original[:, i])
        np.testing.assert_allclose(synth_line.get_ydata(), synth[:, i])
    assert [t.get_text() for t in fig.axes[0].get_legend().get_texts()] == ["original", "CDBN", "nod"]


def test_walktalk_figures_plot_the_given_table():
    """The stroke-peak histogram's counts per gait and method are the table's, with each method's share
    of peaks in contact in the legend; the elbow-bend scatter shows each splice once, with the table's
    correlation in the title."""
    import pandas as pd

    from convsynth_jax.figures.walktalk import elbow_bend_figure, peak_phase_figure

    rng = np.random.default_rng(1)
    n = 40
    df = pd.DataFrame({"gait": np.tile(["walk", "jog"], n // 2), "method": np.repeat(["naive", "stylized"], n // 2),
                       "gait_phase": rng.uniform(size=n), "peak_in_contact": rng.uniform(size=n) < 0.5,
                       "loop_elbow_bend_deg": rng.uniform(10, 40, n), "elbow_bend_deg": rng.uniform(10, 40, n)})
    fig = peak_phase_figure(df)
    assert [ax.get_title() for ax in fig.axes] == ["walk: stroke peak vs gait phase", "jog: stroke peak vs gait phase"]
    bins = np.linspace(0, 1, 21)
    for ax, gait in zip(fig.axes, ("walk", "jog")):
        labels = [t.get_text() for t in ax.get_legend().get_texts()]
        assert len(ax.patches) == len(labels) == 2
        for patch, label, method in zip(ax.patches, labels, ("naive", "stylized")):
            d = df[(df["gait"] == gait) & (df["method"] == method)]
            want, _ = np.histogram(d["gait_phase"], bins=bins)
            y = patch.get_xy()[:, 1]           # a step outline: each bin's count twice, between the edges
            np.testing.assert_allclose(y[1:2 * len(want) + 1:2], want)
            assert label == f"{method} ({100 * d['peak_in_contact'].mean():.0f}% in contact)"
    fig = elbow_bend_figure(df)
    for ax, method in zip(fig.axes, ("naive", "stylized")):
        d = df[df["method"] == method]
        pts = np.concatenate([c.get_offsets() for c in ax.collections])
        want = np.concatenate([d.loc[d["gait"] == g, ["loop_elbow_bend_deg", "elbow_bend_deg"]].to_numpy()
                               for g in ("walk", "jog")])
        np.testing.assert_allclose(pts, want)
        r = np.corrcoef(d["loop_elbow_bend_deg"], d["elbow_bend_deg"])[0, 1]
        assert ax.get_title() == f"{method}: r = {r:.2f}"
