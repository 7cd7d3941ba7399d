import numpy as np
import pytest
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from convsynth_jax.annotate.types import FrameAudio
from convsynth_jax.graph import build_database, build_graph, load_graph
from convsynth_jax.graph.build import k_step_costs
from convsynth_jax.graph.cost import candidate_edges
from convsynth_jax.graph.reference import build_graph_reference, reference_edges
from convsynth_jax.skeleton import Motion, Skeleton
from tolerances import COST_FLOAT32, COST_FLOAT64, THRESHOLD_TIE, enable_x64


def random_clips(rng, n_clips=3, frames=120, joints=5):
    skel = Skeleton(tuple(f"j{j}" for j in range(joints)), tuple(range(-1, joints - 1)),
                    np.tile([0.0, 10.0, 0.0], (joints, 1)), tuple(("Zrotation", "Xrotation", "Yrotation") for _ in range(joints)))
    clips = []
    for c in range(n_clips):
        # smooth random rotations: a few sinusoids per joint, so some poses recur
        t = np.arange(frames)[:, None] / 30.0
        ang = 0.4 * np.sin(2 * np.pi * rng.uniform(0.2, 0.8, (1, joints * 3)) * t + rng.uniform(0, 6, (1, joints * 3)))
        from scipy.spatial.transform import Rotation

        q = Rotation.from_euler("ZXY", ang.reshape(-1, 3)).as_quat()[:, [3, 0, 1, 2]].reshape(frames, joints, 4)
        tr = np.broadcast_to(skel.offsets, (frames, joints, 3)).copy()
        lab = np.zeros(frames, np.int8)
        lab[frames // 3: frames // 2] = 1
        fa = FrameAudio(lab, np.where(lab > 0, frames // 3, -1).astype(np.int32),
                        np.where(lab > 0, frames // 2, -1).astype(np.int32), np.where(lab > 0, frames // 3 + 5, -1).astype(np.int32))
        clips.append((f"clip{c}", Motion(skel, q, tr, 30.0), fa, None))
    return clips


def edge_set(a, b, c, ref_cost, thr):
    keep = np.abs(ref_cost - thr) > THRESHOLD_TIE * thr
    return set(zip(a[keep].tolist(), b[keep].tolist()))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_fast_kernel_gives_exactly_the_reference_edges(seed):
    rng = np.random.default_rng(seed)
    db = build_database(random_clips(rng))
    src = np.flatnonzero(rng.random(db.num_frames) < 0.4)
    dst = np.flatnonzero(rng.random(db.num_frames) < 0.4)
    w = db.weights.astype(np.float32)
    ra, rb, rc = reference_edges(db.positions, db.velocities, w, 0.05, src, dst, db.clip, np.inf, 4)
    thr = float(np.quantile(rc, 0.1))
    ra, rb, rc = reference_edges(db.positions, db.velocities, w, 0.05, src, dst, db.clip, thr, 4)
    fa, fb, fc = candidate_edges(db.positions, db.velocities, w, 0.05, src, dst, db.clip, thr, 4, tile=32, n_pivots=4)
    # every tie-free reference pair is found; no pair beyond the tie band is added
    ref_all = dict(zip(zip(ra.tolist(), rb.tolist()), rc))
    fast = dict(zip(zip(fa.tolist(), fb.tolist()), fc))
    assert edge_set(ra, rb, rc, rc, thr) <= set(fast)
    extra = set(fast) - set(ref_all)
    assert all(abs(fast[e] - thr) <= THRESHOLD_TIE * thr + 1e-3 for e in extra)
    common = sorted(set(fast) & set(ref_all))
    np.testing.assert_allclose([fast[e] for e in common], [ref_all[e] for e in common], rtol=COST_FLOAT32)


def test_kernel_in_float64_matches_reference_tightly():
    rng = np.random.default_rng(5)
    db = build_database(random_clips(rng, 2, 60))
    src = np.arange(0, db.num_frames, 3)
    dst = np.arange(1, db.num_frames, 4)
    w = db.weights
    with enable_x64():
        from convsynth_jax.graph.cost import pair_distance
        import jax.numpy as jnp

        d = np.asarray(pair_distance(jnp.asarray(db.positions[src], jnp.float64), jnp.asarray(db.velocities[src], jnp.float64),
                                     jnp.asarray(db.positions[dst], jnp.float64), jnp.asarray(db.velocities[dst], jnp.float64),
                                     jnp.asarray(w, jnp.float64), 0.3))
    ra, rb, rc = reference_edges(db.positions, db.velocities, w, 0.3, src, dst, db.clip, np.inf, -1)
    ref = np.zeros((src.size, dst.size))
    ref[np.searchsorted(src, ra), np.searchsorted(dst, rb)] = rc
    np.testing.assert_allclose(d, ref, rtol=COST_FLOAT64)


def test_tile_skipping_happens_and_is_exact():
    rng = np.random.default_rng(3)
    db = build_database(random_clips(rng, 4, 200))
    idx = np.arange(db.num_frames)
    stats = {}
    w = db.weights.astype(np.float32)
    fa, fb, _ = candidate_edges(db.positions, db.velocities, w, 0.05, idx, idx, db.clip, 0.5, 4, tile=64, stats=stats)
    ra, rb, rc = reference_edges(db.positions, db.velocities, w, 0.05, idx, idx, db.clip, 0.5, 4)
    assert stats["tiles_skipped"] > 0
    assert edge_set(ra, rb, rc, rc, 0.5) <= set(zip(fa.tolist(), fb.tolist()))


def test_full_builder_equals_reference_builder_and_graph_invariants(tmp_path):
    rng = np.random.default_rng(7)
    db = build_database(random_clips(rng, 3, 150))
    g = build_graph(db)
    r = build_graph_reference(db)
    assert g.meta["threshold"] == pytest.approx(r.meta["threshold"])
    ef, er = g.edges_frame(), r.edges_frame()
    key = ["source_file", "source_frame", "target_file", "target_frame"]
    assert set(map(tuple, ef[key].values)) == set(map(tuple, er[key].values))
    # original transitions cost 0; synthetic ones below the threshold; one strongly connected component
    assert (ef.loc[~ef["synthetic"], "cost"] == 0).all()
    assert (ef.loc[ef["synthetic"], "cost"] < g.meta["threshold"]).all()
    syn = ef[ef["synthetic"]]
    assert ((syn["source_file"] != syn["target_file"]) | ((syn["target_frame"] - 1 - syn["source_frame"]).abs() > g.meta["min_gap_frames"])).all()
    src = np.repeat(np.arange(g.num_states), np.diff(g.indptr))
    n, _ = connected_components(csr_matrix((np.ones(g.num_edges), (src, g.indices)), shape=(g.num_states,) * 2),
                                directed=True, connection="strong")
    assert n == 1
    # key states only on synthetic edges; audio-change frames are key states
    assert g.is_key[src[g.synthetic]].all() and g.is_key[g.indices[g.synthetic]].all()
    assert 0.15 < g.meta["key_fraction"] < 0.3
    # save / load round trip
    g2 = load_graph(g.save(tmp_path / "g.npz"))
    assert g2.num_edges == g.num_edges and g2.meta["threshold"] == g.meta["threshold"]
    np.testing.assert_array_equal(g2.indices, g.indices)


def test_k_step_costs_reference():
    rng = np.random.default_rng(9)
    db = build_database(random_clips(rng, 2, 40))
    c = k_step_costs(db, 3, 0.5)
    i = 5
    exp = (np.linalg.norm(db.positions[i] - db.positions[i + 2], axis=-1) @ db.weights
           + 0.5 * np.linalg.norm(db.velocities[i] - db.velocities[i + 2], axis=-1) @ db.weights)
    assert c[i] == pytest.approx(exp, rel=1e-4)
    assert c.size == 2 * (40 - 3)


def test_real_bandai_clips_fast_equals_reference(bandai_dir):
    from convsynth_jax.graph.database import bvh_folder_clips

    clips = bvh_folder_clips(bandai_dir, "*wave-both-hands_normal_00[1-4].bvh")
    db = build_database(clips)
    g, r = build_graph(db), build_graph_reference(db)
    key = ["source_file", "source_frame", "target_file", "target_frame"]
    ef, er = g.edges_frame(), r.edges_frame()
    assert g.num_states > 0 and len(ef) == len(er)
    assert set(map(tuple, ef[key].values)) == set(map(tuple, er[key].values))


def test_bad_database_inputs():
    from convsynth_jax.errors import GraphError

    rng = np.random.default_rng(0)
    clips = random_clips(rng, 2, 30)
    other = random_clips(rng, 1, 30, joints=4)[0]
    with pytest.raises(GraphError, match="another skeleton"):
        build_database(clips + [("odd", other[1], None, None)])
    with pytest.raises(GraphError, match="no clips"):
        build_database([])


def test_batched_features_equal_per_clip_features():
    from convsynth_jax.graph.database import batched_features
    from convsynth_jax.kinematics import pose_features

    rng = np.random.default_rng(11)
    clips = random_clips(rng, 3, 47)
    P, V = batched_features([c[1] for c in clips])
    start = 0
    for _, m, _, _ in clips:
        f = pose_features(m)
        np.testing.assert_allclose(P[start:start + m.num_frames], np.asarray(f.positions), atol=1e-4)
        np.testing.assert_allclose(V[start:start + m.num_frames], np.asarray(f.velocities), atol=1e-2)
        start += m.num_frames
