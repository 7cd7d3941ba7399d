"""The whole construction (graph/build.py, keystates.py, database.py) against the NumPy reference
builder and against hand-written definitions of key states, k-step costs, w_v, local minima and the
out-degree cap."""
import numpy as np
import pytest
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial.transform import Rotation

from convsynth_jax.annotate.types import FrameAudio
from convsynth_jax.errors import ConfigError, GraphError, MissingFileError
from convsynth_jax.graph import build_database, build_graph, load_graph
from convsynth_jax.graph.build import _cap_degree, _local_minima, auto_w_v, k_step_costs
from convsynth_jax.graph.params import GraphParams
from convsynth_jax.graph.keystates import audio_change_states, key_states, keyframes, pose_change
from convsynth_jax.testing.graph_reference import build_graph_reference, reference_cost_matrix
from convsynth_jax.skeleton import Motion, Skeleton

from tolerances import COST_FLOAT32, THRESHOLD_TIE

GP = GraphParams()

EDGE = ["source_file", "source_frame", "target_file", "target_frame"]


def chain_skeleton(joints=6):
    return Skeleton(tuple(f"j{j}" for j in range(joints)), tuple(range(-1, joints - 1)),
                    np.tile([0.0, 10.0, 0.0], (joints, 1)), tuple(("Zrotation", "Xrotation", "Yrotation") for _ in range(joints)))


def random_clips(seed, n_clips=3, frames=150, joints=6, audio=True):
    """Smooth random rotations (sinusoids: poses recur within and across clips) and, with audio,
    an own label switching on in the middle third and a partner label on a later stretch."""
    rng = np.random.default_rng(seed)
    skel = chain_skeleton(joints)
    clips = []
    for c in range(n_clips):
        t = np.arange(frames)[:, None] / 30.0
        ang = 0.5 * np.sin(2 * np.pi * rng.uniform(0.2, 0.9, (1, joints * 3)) * t + rng.uniform(0, 6, (1, joints * 3)))
        q = Rotation.from_euler("ZXY", ang.reshape(-1, 3)).as_quat()[:, [3, 0, 1, 2]].reshape(frames, joints, 4)
        tr = np.broadcast_to(skel.offsets, (frames, joints, 3)).copy()
        tr[:, 0] += np.cumsum(rng.normal(0, 0.5, (frames, 3)), 0)  # root wanders: features are root-relative
        own = partner = None
        if audio:
            lab = np.zeros(frames, np.int8)
            lab[frames // 3: 2 * frames // 3] = 1
            seg = np.where(lab > 0, frames // 3, -1).astype(np.int32)
            own = FrameAudio(lab, seg, np.where(lab > 0, 2 * frames // 3, -1).astype(np.int32), seg)
            plab = np.zeros(frames, np.int8)
            plab[frames // 2 + c: frames // 2 + c + 20] = 3
            pseg = np.where(plab > 0, frames // 2 + c, -1).astype(np.int32)
            partner = FrameAudio(plab, pseg, np.where(plab > 0, frames // 2 + c + 20, -1).astype(np.int32), pseg)
        clips.append((f"clip{c}", Motion(skel, q, tr, 30.0), own, partner))
    return clips


@pytest.fixture(scope="module")
def db():
    return build_database(random_clips(7))


@pytest.fixture(scope="module")
def graphs(db):
    return build_graph(db, GP), build_graph_reference(db, GP)


def test_fast_builder_gives_the_reference_graph(graphs):
    g, r = graphs
    assert g.meta["threshold"] == r.meta["threshold"]  # shared stages are identical
    ef, er = g.edges_frame(), r.edges_frame()
    thr = g.meta["threshold"]
    ref_cost = {tuple(k): c for k, c in zip(er[EDGE].values.tolist(), er["cost"])}
    fast_cost = {tuple(k): c for k, c in zip(ef[EDGE].values.tolist(), ef["cost"])}
    tie = {k for k, c in ref_cost.items() if abs(c - thr) <= THRESHOLD_TIE * thr}
    assert set(fast_cost) - tie == set(ref_cost) - tie
    common = sorted(set(fast_cost) & set(ref_cost))
    np.testing.assert_allclose([fast_cost[k] for k in common], [ref_cost[k] for k in common], rtol=COST_FLOAT32, atol=1e-6)
    assert g.num_states == r.num_states and (ef["synthetic"].sum() > 0)


def test_graph_invariants(db, graphs):
    g, _ = graphs
    ef = g.edges_frame()
    m = g.meta
    thr, gap = m["threshold"], m["min_gap_frames"]
    # original transitions: consecutive frames of one clip, cost 0
    orig = ef[~ef["synthetic"]]
    assert (orig["cost"] == 0).all()
    assert ((orig["source_file"] == orig["target_file"]) & (orig["target_frame"] == orig["source_frame"] + 1)).all()
    # synthetic transitions: below the threshold, between key states, never trivial neighbours
    syn = ef[ef["synthetic"]]
    assert (syn["cost"] < thr).all()
    assert ((syn["source_file"] != syn["target_file"]) | ((syn["target_frame"] - 1 - syn["source_frame"]).abs() > gap)).all()
    src = np.repeat(np.arange(g.num_states), np.diff(g.indptr))
    assert g.is_key[src[g.synthetic]].all() and g.is_key[g.indices[g.synthetic]].all()
    # each synthetic cost is Eq. 3-4 on pose i and pose j-1 (recomputed from the database)
    base = dict(zip(db.clip_names, db.offsets[:-1]))
    i = np.array([base[f] + s for f, s in zip(syn["source_file"], syn["source_frame"])])
    j1 = np.array([base[f] + s - 1 for f, s in zip(syn["target_file"], syn["target_frame"])])
    pick = np.random.default_rng(0).choice(i.size, min(200, i.size), replace=False)
    ref = [reference_cost_matrix(db.positions[[a]], db.velocities[[a]], db.positions[[b]], db.velocities[[b]],
                                 db.weights, m["w_v"])[0, 0] for a, b in zip(i[pick], j1[pick])]
    np.testing.assert_allclose(syn["cost"].values[pick], ref, rtol=COST_FLOAT32)
    # one strongly connected component, CSR sorted by source then target
    n, _ = connected_components(csr_matrix((np.ones(g.num_edges), (src, g.indices)), shape=(g.num_states,) * 2),
                                directed=True, connection="strong")
    assert n == 1
    assert np.all(np.diff(src * g.num_states + g.indices) > 0)
    # audio status travels with the state
    lab = {(c, f): l for c, f, l in zip(db.clip, db.frame, db.own.label)}
    assert all(lab[(c, f)] == l for c, f, l in zip(g.clip, g.frame, g.own_label))
    for key in ("threshold", "w_v", "k", "quantile", "distribution", "fit_table", "joint_weights", "joint_names",
                "remove_yaw", "up_axis", "num_frames", "num_key_states", "key_fraction", "num_states_before_scc",
                "num_edges_before_scc", "num_states", "num_edges", "seconds"):
        assert key in m, key
    assert m["num_states"] == g.num_states <= m["num_states_before_scc"] == db.num_frames


def test_save_load_round_trip(graphs, tmp_path):
    g, _ = graphs
    h = load_graph(g.save(tmp_path / "g.npz"))
    for name in g._ARRAYS:
        np.testing.assert_array_equal(getattr(h, name), getattr(g, name))
    assert h.meta["threshold"] == g.meta["threshold"] and h.clip_names == g.clip_names
    assert list(h.edges_frame().columns) == ["source_file", "source_frame", "target_file", "target_frame", "cost", "synthetic"]


def test_key_states(db):
    keys, step = key_states(db, 0.25)
    assert abs(keys.mean() - 0.25) < 0.01
    # audio-status changes (own or partner) and clip starts are always key states
    assert keys[audio_change_states(db)].all()
    for c in range(len(db.clip_names)):
        a = db.offsets[c]
        lab = db.own.label[a:db.offsets[c + 1]]
        assert keys[a + np.flatnonzero(np.diff(lab)) + 1].all()
    # keyframes: one each time the accumulated pose change crosses a multiple of the step (loop reference)
    ch = pose_change(db)
    ref = np.zeros(db.num_frames, bool)
    for a, b in zip(db.offsets[:-1], db.offsets[1:]):
        acc = 0.0
        for t in range(a, b):
            before = acc
            acc += ch[t]
            ref[t] = t > a and np.floor(acc / step) > np.floor(before / step)
    np.testing.assert_array_equal(keyframes(db, step), ref)
    # more keyframes where joints move more
    k = keyframes(db, step)
    fast = ch > np.median(ch)
    assert k[fast].mean() > k[~fast].mean()
    assert key_states(db, 1.0)[0].all()


def test_k_step_costs_and_auto_w_v(db):
    k = 3
    c = k_step_costs(db, k, 0.4)
    i = np.array([t for t in range(db.num_frames - k) if db.clip[t] == db.clip[t + k]])
    ref = np.array([reference_cost_matrix(db.positions[[t]], db.velocities[[t]], db.positions[[t + k - 1]],
                                          db.velocities[[t + k - 1]], db.weights, 0.4)[0, 0] for t in i])
    np.testing.assert_allclose(c, ref, rtol=COST_FLOAT32, atol=1e-6)
    # auto w_v: mean position term / mean velocity term of D(i, i+k-1) over every pair (i, i+k-1)
    # inside one clip (fewer than the 50,000-pair sample here, so all of them)
    a = np.array([t for t in range(db.num_frames - k + 1) if db.clip[t] == db.clip[t + k - 1]])
    b = a + k - 1
    dp = np.linalg.norm(db.positions[a] - db.positions[b], axis=-1) @ db.weights
    dv = np.linalg.norm(db.velocities[a] - db.velocities[b], axis=-1) @ db.weights
    assert auto_w_v(db, k) == pytest.approx(dp.mean() / dv.mean(), rel=1e-5)


def test_local_minima_and_degree_cap_match_slow_definitions():
    rng = np.random.default_rng(3)
    a = rng.integers(0, 30, 600)
    j = rng.integers(0, 30, 600)
    uniq = np.unique(a * 100 + j)
    a, j = uniq // 100, uniq % 100
    c = rng.random(a.size).astype(np.float32)
    best = {(x, y): z for x, y, z in zip(a, j, c)}
    keep = [all(best.get((x + dx, y + dy), np.inf) >= z for dx in (-1, 0, 1) for dy in (-1, 0, 1) if dx or dy)
            for x, y, z in zip(a, j, c)]
    la, lj, _ = _local_minima(a, j, c)
    assert set(zip(la, lj)) == {(x, y) for x, y, k in zip(a, j, keep) if k}
    ca, cj, cc = _cap_degree(a, j, c, 3)
    for s in np.unique(a):
        mine = sorted(c[a == s])[:3]
        np.testing.assert_array_equal(np.sort(cc[ca == s]), mine)


def test_degree_cap_inside_the_kernel_equals_capping_afterwards(db):
    g = build_graph(db, GraphParams(max_out_degree=2))
    full = build_graph(db, GP)
    ef = g.edges_frame()
    syn = ef[ef["synthetic"]]
    assert syn.groupby(["source_file", "source_frame"]).size().max() <= 2
    assert g.meta["num_synthetic_before_scc"] < full.meta["num_synthetic_before_scc"]


def test_bad_inputs(db, tmp_path):

    with pytest.raises(GraphError, match="max_edges"):
        build_graph(db, GraphParams(max_edges=10))
    clips = random_clips(0, 2, 30, audio=False)
    other = random_clips(0, 1, 30, joints=4, audio=False)[0]
    with pytest.raises(GraphError, match="another skeleton"):
        build_database(clips + [("odd", other[1], None, None)])
    with pytest.raises(GraphError, match="no clips"):
        build_database([])
    from convsynth_jax.graph.database import bvh_folder_clips

    with pytest.raises(MissingFileError):
        bvh_folder_clips(tmp_path / "absent")
    with pytest.raises(GraphError, match="no files"):
        bvh_folder_clips(tmp_path)


def test_real_bandai_clips_fast_equals_reference(bandai_dir):
    from convsynth_jax.graph.database import bvh_folder_clips

    db = build_database(bvh_folder_clips(bandai_dir, "*wave-both-hands_normal_00[1-4].bvh"))
    g, r = build_graph(db, GP), build_graph_reference(db, GP)
    thr = g.meta["threshold"]
    ef, er = g.edges_frame(), r.edges_frame()
    tie = {tuple(k) for k, c in zip(er[EDGE].values.tolist(), er["cost"]) if abs(c - thr) <= THRESHOLD_TIE * thr}
    assert g.num_states > 0 and ef["synthetic"].sum() > 0
    assert set(map(tuple, ef[EDGE].values.tolist())) - tie == set(map(tuple, er[EDGE].values.tolist())) - tie


def test_batched_features_equal_per_clip_features():
    from convsynth_jax.kinematics import batched_pose_features
    from convsynth_jax.kinematics import pose_features

    clips = random_clips(11, 3, 47)
    P, V = batched_pose_features([c[1] for c in clips])
    start = 0
    for _, m, _, _ in clips:
        f = pose_features(m)
        np.testing.assert_allclose(P[start:start + m.num_frames], np.asarray(f.positions), atol=1e-4)
        np.testing.assert_allclose(V[start:start + m.num_frames], np.asarray(f.velocities), atol=1e-2)
        start += m.num_frames


def test_scc_collapse_warns_and_is_marked_in_meta(db, caplog):
    """Without synthetic transitions every clip is a chain: the largest SCC is one state."""
    from convsynth_jax.graph.build import assemble_graph

    keys = np.zeros(db.num_frames, bool)
    none = np.zeros(0, np.int64)
    with caplog.at_level("WARNING", logger="convsynth_jax.graph.build"):
        g = assemble_graph(db, keys, none, none, np.zeros(0, np.float32), {"k": 2})
    assert g.num_states == 1 and g.num_edges == 0
    assert "keeps 1 of 450 states" in g.meta["scc_warning"] and "k = 2" in g.meta["scc_warning"]
    assert any(r.levelname == "WARNING" and "strongly connected" in r.getMessage() for r in caplog.records)
    # a healthy graph carries an empty warning and logs none
    caplog.clear()
    with caplog.at_level("WARNING", logger="convsynth_jax.graph.build"):
        g = build_graph(db, GP)
    assert g.num_states >= 0.5 * db.num_frames and g.meta["scc_warning"] == ""
    assert not [r for r in caplog.records if "strongly connected" in r.getMessage()]


def test_fitting_only_the_configured_distribution_gives_the_same_graph(db, graphs):
    """graph.fit_all_candidates=false (default) fits only Johnson SB; with true every candidate is
    fitted into meta['fit_table'] and the threshold, edges and costs are the same."""
    import dataclasses

    from convsynth_jax.stats.fits import CANDIDATES

    g, _ = graphs
    h = build_graph(db, dataclasses.replace(GP, fit_all_candidates=True))
    assert [r["distribution"] for r in g.meta["fit_table"]] == ["johnsonsb"]
    assert sorted(r["distribution"] for r in h.meta["fit_table"]) == sorted(CANDIDATES)
    sb = next(r for r in h.meta["fit_table"] if r["distribution"] == "johnsonsb")
    assert sb["params"] == g.meta["fit_table"][0]["params"] and sb["rss"] == g.meta["fit_table"][0]["rss"]
    assert h.meta["threshold"] == g.meta["threshold"]
    for name in g._ARRAYS:
        np.testing.assert_array_equal(getattr(h, name), getattr(g, name))
    auto = build_graph(db, dataclasses.replace(GP, distribution="auto"))
    assert len(auto.meta["fit_table"]) == len(CANDIDATES)


def test_graph_statistics_agree_across_the_three_tasks(db, graphs):
    """graph/statistics.py: the Table 2 row is the graph's, the report's fit (from the graph) and the
    figure4 task's fit of every candidate choose the same threshold for a k, and the graph given for
    a k is used rather than rebuilt."""
    import dataclasses
    import json

    from convsynth_jax.graph.statistics import graph_statistics

    g = graphs[0]
    ks = [GP.k, GP.k + 1]
    built = graph_statistics(db, GP, ks, "c", graphs={GP.k: g})
    fitted = graph_statistics(db, GP, ks, "c", build_graphs=False, fit_all=True)
    row = built.table2[0]
    assert row["k"] == GP.k and row["states_after_scc"] == g.num_states and row["edges_after_scc"] == g.num_edges
    assert row["seconds"] == g.meta["seconds"]          # the given graph, not a rebuilt one
    other = build_graph(db, dataclasses.replace(GP, k=GP.k + 1))
    assert built.table2[1]["states_before_scc"] == other.meta["num_states_before_scc"]
    for k in ks:
        mine = [f for f in built.fits if f["k"] == k]
        chosen = [f for f in fitted.fits if f["k"] == k and f["chosen"]]
        assert len(mine) == 1 and len(chosen) == 1
        assert mine[0]["distribution"] == chosen[0]["distribution"]
        assert mine[0]["threshold"] == pytest.approx(chosen[0]["threshold"], rel=1e-9)
        assert json.loads(mine[0]["params"]) == pytest.approx(json.loads(chosen[0]["params"]), rel=1e-9)
        assert mine[0]["w_v"] == pytest.approx(chosen[0]["w_v"], rel=1e-12)
        for st in (built, fitted):
            h = [r for r in st.histograms if r["k"] == k]
            assert len(h) == GP.fit_bins
            assert sum(r["density"] * (r["bin_right"] - r["bin_left"]) for r in h) == pytest.approx(1.0)
    with pytest.raises(ConfigError):
        graph_statistics(db, GP, ks, build_graphs=False)
