"""SMPL-X parameter files (BEAT2 .npz) to BVH: the converter against the slow Rodrigues + textbook
Euler reference (convsynth_jax/testing/smplx_reference.py), model files, bad input, task=convert."""
from __future__ import annotations

import numpy as np
import pytest

from conftest import shared_path
from convsynth_jax.config import compose, run_task
from convsynth_jax.errors import FormatError, MissingFileError
from convsynth_jax.io import save_bvh
from convsynth_jax.io.smplx import SMPLX_TEMPLATE_JOINTS, load_smplx_model, smplx_motion, smplx_rest_joints
from convsynth_jax.rig import SMPLX_JOINT_NAMES
from convsynth_jax.testing import smplx_reference as ref


def fake_take(path, T=12, J=55, seed=0, **extra):
    rng = np.random.default_rng(seed)
    poses = rng.normal(0, 0.8, (T, 3 * J)).astype(np.float32)
    poses[0, :3] = 0.0                      # an identity rotation
    data = {"poses": poses, "trans": rng.normal(0, 0.5, (T, 3)), "betas": rng.normal(0, 1, 300).astype(np.float32),
            "mocap_frame_rate": np.int32(30), **extra}
    np.savez(path, **{k: v for k, v in data.items() if v is not None})
    return data


def compare(bvh_path, poses, trans, rest_pelvis_m):
    """(per-joint rotation errors in degrees, max root position error in cm) of a written BVH against
    the reference conversion of ``poses``."""
    names, chans, rows = ref.read_bvh_channels(bvh_path)
    J = poses.shape[1] // 3
    want = ref.reference_local_matrices(poses)
    errs, root_err = [], 0.0
    for f, row in enumerate(rows):
        col = 0
        for name, ch in zip(names, chans):
            j = SMPLX_JOINT_NAMES.index(name)
            vals = dict(zip(ch, row[col:col + len(ch)]))
            col += len(ch)
            assert ch[-3:] == ["Zrotation", "Xrotation", "Yrotation"]
            got = ref.euler_zxy_deg_to_matrix(vals["Zrotation"], vals["Xrotation"], vals["Yrotation"])
            errs.append(ref.rotation_angle_deg(want[f][j], got))
            if "Xposition" in vals:
                pos = np.array([vals["Xposition"], vals["Yposition"], vals["Zposition"]])
                root_err = max(root_err, float(np.abs(pos - (np.asarray(trans[f]) + rest_pelvis_m) * 100).max()))
        assert col == len(row) and len(names) == J
    return np.array(errs), root_err


def test_random_take_matches_reference(tmp_path):
    d = fake_take(tmp_path / "t.npz")
    m = smplx_motion(tmp_path / "t.npz")
    save_bvh(m, tmp_path / "t.bvh")
    errs, root_err = compare(tmp_path / "t.bvh", d["poses"], d["trans"], SMPLX_TEMPLATE_JOINTS[0])
    assert errs.max() < 0.01 and root_err < 1e-3
    # the Euler angles themselves, where the reference's decomposition is away from gimbal lock
    names, chans, rows = ref.read_bvh_channels(tmp_path / "t.bvh")
    eul = ref.reference_local_euler_zxy_deg(d["poses"])
    j = names.index("left_elbow")
    col = sum(len(c) for c in chans[:j])
    for f in range(len(rows)):
        a = eul[f][SMPLX_JOINT_NAMES.index("left_elbow")]
        if abs(a[1]) < 80:
            assert np.allclose(rows[f][col:col + 3], a, atol=1e-3)


def test_hands_only_and_body_only_takes(tmp_path):
    for J, n in ((52, 52), (22, 22)):
        d = fake_take(tmp_path / f"t{J}.npz", J=J)
        m = smplx_motion(tmp_path / f"t{J}.npz")
        assert m.skeleton.num_joints == n and ("jaw" in m.skeleton.names) == (J == 55)
        save_bvh(m, tmp_path / f"t{J}.bvh")
        names, _, _ = ref.read_bvh_channels(tmp_path / f"t{J}.bvh")
        if J == 52:   # SMPL-H order: body then hands, no jaw or eyes
            order = [*range(22), *range(25, 55)]
            poses55 = np.zeros((len(d["poses"]), 165), np.float32)
            for k, j in enumerate(order):
                poses55[:, 3 * j:3 * j + 3] = d["poses"][:, 3 * k:3 * k + 3]
            want = ref.reference_local_matrices(poses55[:2])
            _, chans, rows = ref.read_bvh_channels(tmp_path / "t52.bvh")
            col = sum(len(c) for c in chans[:names.index("right_thumb3")])
            got = ref.euler_zxy_deg_to_matrix(*rows[1][col:col + 3])
            assert ref.rotation_angle_deg(want[1][SMPLX_JOINT_NAMES.index("right_thumb3")], got) < 0.01


@pytest.mark.parametrize("change, needle", [
    ({"poses": None}, "lacks ['poses']"),
    ({"mocap_frame_rate": None}, "mocap_frame_rate"),
    ({"poses": np.zeros((12, 100))}, "poses has shape"),
    ({"trans": np.zeros((11, 3))}, "trans has shape"),
    ({"trans": np.where(np.arange(36).reshape(12, 3) == 20, np.nan, 0.0)}, "frame 6"),
    ({"mocap_frame_rate": np.float64(0)}, "positive"),
])
def test_bad_takes_name_the_file(tmp_path, change, needle):
    p = tmp_path / "bad.npz"
    fake_take(p, **change)
    with pytest.raises(FormatError, match="bad.npz") as e:
        run_task(compose(["task=convert", f"path={p}", f"task.out={tmp_path / 'o.bvh'}"]), tmp_path / "run")
    assert needle in str(e.value)
    assert not (tmp_path / "o.bvh").exists() and not list(tmp_path.glob(".o.bvh*"))


def test_missing_and_foreign_files(tmp_path):
    with pytest.raises(MissingFileError, match="nope.npz"):
        smplx_motion(tmp_path / "nope.npz")
    (tmp_path / "junk.npz").write_text("not a zip")
    with pytest.raises(FormatError, match="junk.npz"):
        smplx_motion(tmp_path / "junk.npz")


def fake_model(path, V=40, S=16, J=55, seed=1):
    rng = np.random.default_rng(seed)
    jr = rng.random((J, V))
    jr /= jr.sum(1, keepdims=True)
    m = {"J_regressor": jr, "v_template": rng.normal(0, 0.3, (V, 3)), "shapedirs": rng.normal(0, 0.01, (V, 3, S)),
         "kintree_table": np.zeros((2, J))}
    np.savez(path, **m)
    return m


def test_model_file_gives_rest_joints_from_betas(tmp_path):
    model = fake_model(tmp_path / "SMPLX_FAKE.npz")
    d = fake_take(tmp_path / "t.npz")
    betas = d["betas"].astype(np.float64)
    want = model["J_regressor"] @ (model["v_template"] + model["shapedirs"] @ betas[:16])
    got = smplx_rest_joints(betas, tmp_path / "SMPLX_FAKE.npz")
    assert np.allclose(got, want)
    assert not np.allclose(got, smplx_rest_joints(np.zeros(300), tmp_path / "SMPLX_FAKE.npz"))
    s = run_task(compose(["task=convert", f"path={tmp_path / 't.npz'}", f"task.out={tmp_path / 'o.bvh'}",
                          f"task.smplx_model={tmp_path / 'SMPLX_FAKE.npz'}"]), tmp_path / "run")
    assert s["rest_skeleton"] == "smplx_model"
    errs, root_err = compare(tmp_path / "o.bvh", d["poses"], d["trans"], want[0])
    assert errs.max() < 0.01 and root_err < 1e-3
    text = (tmp_path / "o.bvh").read_text()
    wrist = want[SMPLX_JOINT_NAMES.index("left_wrist")] - want[SMPLX_JOINT_NAMES.index("left_elbow")]
    assert "OFFSET " + " ".join(f"{v:.6f}" for v in wrist * 100) in text


def test_model_file_of_the_wrong_kind(tmp_path):
    np.savez(tmp_path / "take_not_model.npz", poses=np.zeros((2, 165)))
    with pytest.raises(FormatError, match="take_not_model.npz.*lacks"):
        load_smplx_model(tmp_path / "take_not_model.npz")
    fake_model(tmp_path / "smplh.npz", J=52)
    with pytest.raises(FormatError, match="smplh.npz.*52 joints"):
        smplx_rest_joints(np.zeros(10), tmp_path / "smplh.npz")
    (tmp_path / "m.pkl").write_bytes(b"garbage")
    with pytest.raises(FormatError, match="m.pkl"):
        load_smplx_model(tmp_path / "m.pkl")


def test_inspect_reads_npz(tmp_path):
    fake_take(tmp_path / "t.npz", T=7)
    s = run_task(compose(["task=inspect", f"path={tmp_path / 't.npz'}"]), tmp_path / "run")
    assert s["num_frames"] == 7 and s["num_joints"] == 55 and "left_wrist" in s["joints"]


def test_shared_beat2_take_converts_exactly(tmp_path):
    """Acceptance: the shared BEAT2 take's local rotations equal the reference conversion (median
    < 0.5 degrees, 99th percentile < 2) and its root translation is the recording's (x 100 cm)."""
    src = shared_path("beat2", "smplxflame_30", "2_scott_0_1_1.npz")
    s = run_task(compose(["task=convert", f"path={src}", f"task.out={tmp_path / 'scott.bvh'}"]), tmp_path / "run")
    d = np.load(src)
    assert s["num_frames"] == len(d["poses"]) and s["fps"] == 30
    step = 4   # every 4th frame keeps the pure-Python reference within a few seconds
    errs, root_err = compare_every(tmp_path / "scott.bvh", d["poses"], d["trans"], step)
    assert np.median(errs) < 0.5 and np.percentile(errs, 99) < 2.0
    assert root_err < 1e-3


def compare_every(path, poses, trans, step):
    names, chans, rows = ref.read_bvh_channels(path)
    sub = path.with_name("sub.bvh")
    lines = path.read_text().splitlines()
    k = lines.index("MOTION")
    keep = [r for i, r in enumerate(lines[k + 3:]) if i % step == 0]
    sub.write_text("\n".join(lines[:k + 3] + keep) + "\n")
    return compare(sub, poses[::step], trans[::step], SMPLX_TEMPLATE_JOINTS[0])
