"""Hydra app, multirun and launcher smoke tests (basic, joblib, submitit local executor)."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from convsynth_jax.io import save_bvh
from convsynth_jax.skeleton import Motion, Skeleton

REPO = Path(__file__).resolve().parent.parent


def _tiny_bvh(path: Path, frames: int = 12) -> Path:
    skel = Skeleton(("Hips", "Spine", "Head"), (-1, 0, 1), np.array([[0, 90, 0], [0, 10, 0], [0, 20, 0]], float),
                    (("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation"),
                     ("Zrotation", "Xrotation", "Yrotation"), ("Zrotation", "Xrotation", "Yrotation")),
                    ((2, (0.0, 5.0, 0.0)),))
    rot = np.zeros((frames, 3, 4)); rot[..., 0] = 1
    trans = np.broadcast_to(skel.offsets, (frames, 3, 3)).copy()
    trans[:, 0, 0] = np.linspace(0, 5, frames)
    return save_bvh(Motion(skel, rot, trans, 30.0), path)


def _convsynth(args, cwd: Path, timeout=240):
    exe = shutil.which("convsynth") or str(Path(sys.executable).parent / "convsynth")
    env = {**os.environ, "HYDRA_FULL_ERROR": "1"}
    return subprocess.run([exe, *args], cwd=cwd, capture_output=True, text=True, timeout=timeout, env=env)


def _summaries(root: Path):
    return sorted(root.rglob("summary.json"))


def test_single_run_writes_summary(tmp_path):
    f = _tiny_bvh(tmp_path / "a.bvh")
    r = _convsynth(["task=inspect", f"path={f}", f"hydra.run.dir={tmp_path / 'out'}"], tmp_path)
    assert r.returncode == 0, r.stderr[-2000:]
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert s["task"] == "inspect" and s["num_frames"] == 12 and s["num_joints"] == 3


def test_bad_input_gives_clear_error_and_summary(tmp_path):
    bad = tmp_path / "bad.bvh"
    bad.write_text("HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 3 Zrotation Xrotation Yrotation\n}\n")
    r = _convsynth(["task=inspect", f"path={bad}", f"hydra.run.dir={tmp_path / 'out'}"], tmp_path)
    assert r.returncode != 0
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert s["success"] is False and "bad.bvh" in s["error"] and "MOTION" in s["error"]


@pytest.mark.parametrize("launcher", ["basic", "joblib", "submitit_local"])
def test_multirun_launchers(tmp_path, launcher):
    if launcher == "joblib":
        pytest.importorskip("hydra_plugins.hydra_joblib_launcher")
    if launcher == "submitit_local":
        pytest.importorskip("hydra_plugins.hydra_submitit_launcher")
    a, b = _tiny_bvh(tmp_path / "a.bvh", 10), _tiny_bvh(tmp_path / "b.bvh", 14)
    args = ["-m", "task=inspect", f"path={a},{b}", f"hydra.sweep.dir={tmp_path / 'sweep'}"]
    if launcher != "basic":
        args.append(f"hydra/launcher={launcher}")
    if launcher == "joblib":
        args.append("hydra.launcher.n_jobs=2")
    if launcher == "submitit_local":
        args += ["hydra.launcher.timeout_min=5", "hydra.launcher.cpus_per_task=1"]
    r = _convsynth(args, tmp_path)
    assert r.returncode == 0, r.stderr[-3000:]
    frames = sorted(json.loads(p.read_text())["num_frames"] for p in _summaries(tmp_path / "sweep"))
    assert frames == [10, 14]
