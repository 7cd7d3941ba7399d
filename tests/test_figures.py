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
    assert writers == ["figures/save.py"]
    assert not (PKG / "cdbn" / "figures.py").exists() and not (PKG / "walktalk" / "figures.py").exists()


def test_cdbn_and_walktalk_figures_return_figures():
    import pandas as pd

    from convsynth_jax.figures.cdbn import init_ellipses_figure, states_curve_figure, trajectories_figure
    from convsynth_jax.figures.walktalk import elbow_bend_figure, peak_phase_figure

    rng = np.random.default_rng(0)
    comp = {k: {"motion_means": rng.normal(size=(2, 3)), "motion_covariances": np.stack([np.eye(3)] * 2)}
            for k in ("random", "lbg")}
    curves = {"jdbn": {3: {"cca_m": 0.2, "llr": 1.0}, 5: {"cca_m": 0.3, "llr": 1.5}}}
    figs = [init_ellipses_figure(rng.normal(size=(50, 3)), comp), states_curve_figure(curves),
            trajectories_figure(30.0, rng.normal(size=(20, 3)), {"CDBN": rng.normal(size=(20, 3))},
                                np.r_[np.zeros(10), np.ones(10)].astype(int), ("other", "nod"))]
    df = pd.DataFrame({"gait": ["walk", "jog"] * 2, "method": ["naive"] * 2 + ["stylized"] * 2,
                       "gait_phase": rng.uniform(size=4), "peak_in_contact": [True, False, True, True],
                       "loop_elbow_bend_deg": rng.uniform(10, 40, 4), "elbow_bend_deg": rng.uniform(10, 40, 4)})
    figs += [peak_phase_figure(df), elbow_bend_figure(df)]
    assert all(isinstance(f, Figure) for f in figs)
