"""Graph tasks (build_graph, table2, figure4) on a folder of BVH files written here; the dyadic
(synthetic corpus) path of the same tasks runs in tests/test_tasks.py."""
import json

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.transform import Rotation

from convsynth_jax.config import compose, run_task
from convsynth_jax.graph import load_graph
from convsynth_jax.io.bvh import save_bvh
from convsynth_jax.skeleton import Motion, Skeleton


@pytest.fixture(scope="module")
def bvh_root(tmp_path_factory):
    """Four BVH files (one in a subfolder) of a 5-joint chain with recurring smooth motion."""
    root = tmp_path_factory.mktemp("bvh")
    J = 5
    skel = Skeleton(tuple(f"j{j}" for j in range(J)), tuple(range(-1, J - 1)), np.tile([0.0, 10.0, 0.0], (J, 1)),
                    (("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation"),)
                    + tuple(("Zrotation", "Xrotation", "Yrotation") for _ in range(J - 1)))
    rng = np.random.default_rng(0)
    names = ["a.bvh", "b.bvh", "c.bvh", "sub/d.bvh"]
    for k, name in enumerate(names):
        n = 150 + 10 * k
        t = np.arange(n)[:, None] / 30.0
        ang = 0.5 * np.sin(2 * np.pi * rng.uniform(0.3, 0.9, (1, J * 3)) * t + rng.uniform(0, 6, (1, J * 3)))
        ang[:, :3] *= 0.2
        q = Rotation.from_euler("ZXY", ang.reshape(-1, 3)).as_quat()[:, [3, 0, 1, 2]].reshape(n, J, 4)
        tr = np.broadcast_to(skel.offsets, (n, J, 3)).copy()
        tr[:, 0] = [0.0, 90.0, 0.0]
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        save_bvh(Motion(skel, q, tr, 30.0), root / name)
    return root


def cfg(task, root, *extra):
    return compose([f"task={task}", "corpus=bvh_folder", f"corpus.root={root}", "progress=false", *extra])


def test_build_graph_task_writes_graph_and_summary(bvh_root, tmp_path):
    s = run_task(cfg("build_graph", bvh_root), tmp_path)
    g = load_graph(tmp_path / "graph.npz")
    on_disk = json.loads((tmp_path / "summary.json").read_text())
    for key in ("num_frames", "num_key_states", "threshold", "num_states_before_scc", "num_edges_before_scc",
                "num_states", "num_edges", "seconds", "w_v", "joint_weights", "joint_names", "root_relative",
                "remove_yaw"):
        assert on_disk[key] == s[key] and s[key] is not None, key
    assert s["num_states"] == g.num_states and s["num_edges"] == g.num_edges
    assert s["threshold"] == g.meta["threshold"] and s["num_frames"] == 150 + 160 + 170 + 180
    assert s["num_states"] <= s["num_states_before_scc"] == s["num_frames"]
    assert 0.15 < s["num_key_states"] / s["num_frames"] < 0.3  # motion-only key states
    e = g.edges_frame()
    lengths = {"a.bvh": 150, "b.bvh": 160, "c.bvh": 170, "sub/d.bvh": 180}
    assert set(e["source_file"]) <= set(lengths) and e["synthetic"].any()
    assert all(0 <= f < lengths[n] for n, f in zip(e["target_file"], e["target_frame"]))
    # only top-level files with another pattern
    s2 = run_task(cfg("build_graph", bvh_root, "corpus.pattern=*.bvh"), tmp_path / "top")
    assert s2["num_frames"] == 150 + 160 + 170


def test_table2_and_figure4_agree_with_build_graph(bvh_root, tmp_path, caplog):
    with caplog.at_level("WARNING"):
        run_task(cfg("table2", bvh_root), tmp_path / "t2")
    t2 = pd.read_csv(tmp_path / "t2" / "table2.csv")
    assert list(t2["k"]) == [2, 3, 4, 5]
    assert (tmp_path / "t2" / "table2.md").read_text().count("\n") >= 5
    assert (t2["states_after_scc"] <= t2["states_before_scc"]).all()
    assert (t2["edges_after_scc"] <= t2["edges_before_scc"]).all()
    assert t2["threshold"].is_monotonic_increasing  # poses drift further apart over more frames
    # at k = 2 this corpus collapses to one state: the scc_warning column and a WARNING say so
    warned = t2["scc_warning"].fillna("") != ""
    assert (warned == (t2["kept_state_fraction"] < 0.5)).all() and warned.iloc[0]
    assert "strongly connected component at k = 2 keeps" in t2["scc_warning"].iloc[0]
    assert any(r.levelname == "WARNING" and "at k = 2 keeps" in r.getMessage() for r in caplog.records)
    s = run_task(cfg("build_graph", bvh_root, "graph.k=4"), tmp_path / "g4")
    row = t2[t2["k"] == 4].iloc[0]
    assert row["threshold"] == pytest.approx(s["threshold"], rel=1e-12)
    assert (row["states_after_scc"], row["edges_after_scc"]) == (s["num_states"], s["num_edges"])

    run_task(cfg("figure4", bvh_root, "task.ks=[3,4]"), tmp_path / "f4")
    for name in ("figure4.png", "figure4.pdf", "figure4_fits.csv", "figure4_histograms.csv"):
        assert (tmp_path / "f4" / name).stat().st_size > 0
    fits = pd.read_csv(tmp_path / "f4" / "figure4_fits.csv")
    hist = pd.read_csv(tmp_path / "f4" / "figure4_histograms.csv")
    assert (fits.groupby("k")["chosen"].sum() == 1).all() and (fits.groupby("k").size() == 7).all()
    chosen = fits[fits["chosen"]].set_index("k")
    assert (chosen["distribution"] == "johnsonsb").all()
    assert chosen.loc[4, "threshold"] == pytest.approx(s["threshold"], rel=1e-9)
    for k, h in hist.groupby("k"):
        assert np.sum(h["density"] * (h["bin_right"] - h["bin_left"])) == pytest.approx(1.0)


def test_figure4_plot_is_pure_data_to_figure():
    from convsynth_jax.figures.motion_graph import figure4_figure

    edges = np.linspace(0, 10, 11)
    hist = pd.DataFrame({"character": "all", "k": 3, "bin_left": edges[:-1], "bin_right": edges[1:],
                         "density": np.full(10, 0.1)})
    fits = pd.DataFrame({"character": ["all", "all"], "k": [3, 3], "distribution": ["johnsonsb", "gamma"],
                         "params": [json.dumps([0.0, 1.0, -0.1, 10.2]), "[]"], "rss": [0.1, np.inf],
                         "chosen": [True, False], "threshold": [9.0, np.nan]})
    fig = figure4_figure(hist, fits)
    ax = fig.axes[0]
    assert len(ax.patches) == 10 and len(ax.lines) == 2  # chosen curve + threshold line; failed fit skipped
    assert ax.lines[1].get_xdata()[0] == pytest.approx(9.0)

