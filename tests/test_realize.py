"""Realization's vectorized root integration against a plain per-frame loop (SciPy rotations)."""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from convsynth_jax.data.skeleton_seated import seated_skeleton
from convsynth_jax.skeleton import Motion
from convsynth_jax.synth.realize import realize


def _loop_root(source_clips, source_frames, motions, chair, chair_yaw_deg):
    """The obvious version: one frame at a time, SciPy for every rotation."""
    def yaw(q):
        return 2.0 * np.arctan2(q[2], q[0])

    T = len(source_frames)
    vel, rate = np.zeros((T, 3)), np.zeros(T)
    for t, (c, f) in enumerate(zip(source_clips, source_frames)):
        m = motions[c]
        f0, f1 = (f, f + 1) if f + 1 < m.num_frames else (max(f - 1, 0), f)
        y0 = yaw(m.rotations[f0, 0])
        vel[t] = Rotation.from_rotvec([0, -y0, 0]).apply(m.translations[f1, 0] - m.translations[f0, 0])
        rate[t] = (yaw(m.rotations[f1, 0]) - y0 + np.pi) % (2 * np.pi) - np.pi
    heading = np.deg2rad(chair_yaw_deg) + np.concatenate([[0.0], np.cumsum(rate[:-1])])
    pos = np.zeros((T, 3))
    pos[0] = chair
    for t in range(1, T):
        pos[t] = pos[t - 1] + Rotation.from_rotvec([0, heading[t - 1], 0]).apply(vel[t - 1])
    rot = []
    for t, (c, f) in enumerate(zip(source_clips, source_frames)):
        q = motions[c].rotations[f, 0]
        src = Rotation.from_quat(q[[1, 2, 3, 0]])
        tilt = Rotation.from_rotvec([0, -yaw(q), 0]) * src
        rot.append((Rotation.from_rotvec([0, heading[t], 0]) * tilt).as_quat()[[3, 0, 1, 2]])
    return pos, np.array(rot)


def test_root_integration_equals_the_per_frame_loop():
    rng = np.random.default_rng(0)
    skel = seated_skeleton()
    J = skel.num_joints
    motions = {}
    for name in ("a", "b"):
        n = 40
        ang = np.cumsum(rng.normal(0, 0.05, n))  # a wandering heading with some tilt
        tilt = rng.normal(0, 0.1, n)
        rot = np.zeros((n, J, 4)); rot[..., 0] = 1
        r = Rotation.from_euler("YX", np.c_[ang, tilt]).as_quat()
        rot[:, 0] = r[:, [3, 0, 1, 2]]
        trans = np.broadcast_to(skel.offsets, (n, J, 3)).copy()
        trans[:, 0] = np.cumsum(rng.normal(0, 0.5, (n, 3)), axis=0)
        motions[name] = Motion(skel, rot, trans, 30.0, name)
    clips = ["a"] * 25 + ["b"] * 20
    frames = list(range(5, 30)) + list(range(10, 30))
    m = realize(clips, frames, motions, [25], chair=(1.0, 0.0, -60.0), chair_yaw_deg=180.0, blend_frames=0)
    pos, rot = _loop_root(clips, frames, motions, (1.0, 0.0, -60.0), 180.0)
    pos[:, 1] = [motions[c].translations[f, 0, 1] for c, f in zip(clips, frames)]
    np.testing.assert_allclose(m.translations[:, 0], pos, atol=1e-9)
    np.testing.assert_allclose(np.abs(np.sum(m.rotations[:, 0] * rot, -1)), 1.0, atol=1e-9)
