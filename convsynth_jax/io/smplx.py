"""SMPL-X parameter files (BEAT2's ``smplxflame_30/*.npz``, AMASS-style SMPL-H/SMPL-X npz) as Motion.

An SMPL-X take holds per-frame axis-angle rotations ``poses`` (T, 3J) of the model's joints in the
order of :data:`convsynth_jax.rig.SMPLX_JOINT_NAMES` (J = 55: body 0-21, jaw, eyes, hands; J = 52:
SMPL-H, body and hands without jaw and eyes; J = 22: body only), the root translation ``trans``
(T, 3) in metres, the body shape ``betas`` and the capture rate ``mocap_frame_rate``.

Conventions (they make the conversion exact up to the rest skeleton):

* every SMPL-X joint frame is aligned with the world in the rest pose, so the pose vector's
  axis-angle triple of joint j *is* its local rotation relative to its parent; a BVH joint with
  ``OFFSET = J_j - J_parent(j)`` (rest joint positions J) and that rotation reproduces the model's
  skeleton (not its skinned mesh);
* the model's world is Y-up, +Z forward, +X the body's left, as in the project (rotations.py);
* the pelvis lies at ``J_0 + trans`` (the model rotates about its rest pelvis, then translates), so
  the BVH root position is ``(trans + J_0) * 100`` centimetres.

Rest joints: :func:`smplx_rest_joints` computes them exactly from the user's own SMPL-X model file
(``J_regressor @ (v_template + shapedirs @ betas)``, with the take's betas); without one, the
generic template :data:`SMPLX_TEMPLATE_JOINTS` stands in. The template's joint positions are
approximate (a neutral adult of about 1.7 m, within a few centimetres of SMPL-X's neutral mean
shape): bone lengths and so joint *positions* are approximate, while every joint *rotation* and the
root translation are the recording's.
"""
from __future__ import annotations

import pickle
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import FormatError, MissingFileError
from ..rig import SMPLX_JOINT_NAMES, SMPLX_PARENTS
from ..rotations import axis_angle_to_quat
from ..skeleton import Motion, Skeleton

# How many joints a pose vector of each length holds, and which SMPL-X joints they are.
_BODY = tuple(range(22))
_HANDS = tuple(range(25, 55))
JOINT_SETS = {22: _BODY, 52: _BODY + _HANDS, 55: tuple(range(55))}
FRAME_RATE_KEYS = ("mocap_frame_rate", "mocap_framerate")   # BEAT2, AMASS
MODEL_KEYS = ("J_regressor", "v_template", "shapedirs")

ROOT_CHANNELS = ("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")
JOINT_CHANNELS = ("Zrotation", "Xrotation", "Yrotation")
CM_PER_M = 100.0


def _template_joints() -> np.ndarray:
    """(55, 3) metres: the generic rest joints (see the module docstring: approximate)."""
    left_body = {  # SMPL-X-like neutral rest joints of the body (x: the body's left)
        "pelvis": (0.000, -0.345, 0.025), "left_hip": (0.070, -0.436, 0.020), "spine1": (-0.002, -0.226, -0.005),
        "left_knee": (0.104, -0.822, 0.010), "spine2": (0.004, -0.098, 0.005), "left_ankle": (0.088, -1.227, -0.035),
        "spine3": (0.002, -0.040, 0.010), "left_foot": (0.118, -1.282, 0.085), "neck": (0.000, 0.190, -0.015),
        "left_collar": (0.078, 0.102, -0.005), "head": (0.004, 0.257, 0.035), "left_shoulder": (0.164, 0.114, -0.015),
        "left_elbow": (0.414, 0.093, -0.035), "left_wrist": (0.650, 0.098, -0.030),
    }
    pos = {}
    for name, p in left_body.items():
        pos[name] = np.array(p)
        if name.startswith("left_"):
            pos["right_" + name[5:]] = np.array(p) * (-1.0, 1.0, 1.0)
    pos["jaw"] = pos["head"] + (0.0, -0.015, 0.045)
    pos["left_eye_smplhf"] = pos["head"] + (0.032, 0.055, 0.085)
    pos["right_eye_smplhf"] = pos["head"] + (-0.032, 0.055, 0.085)
    # finger bases from the wrist and the two segment lengths (left hand, +x along the fingers)
    fingers = {"index": ((0.088, -0.005, 0.025), 0.034, 0.022), "middle": ((0.094, -0.003, 0.002), 0.037, 0.025),
               "pinky": ((0.072, -0.010, -0.038), 0.025, 0.018), "ring": ((0.085, -0.007, -0.020), 0.033, 0.023)}
    for side, sx in (("left", 1.0), ("right", -1.0)):
        wrist = pos[f"{side}_wrist"]
        for f, (base, l2, l3) in fingers.items():
            b = wrist + np.array(base) * (sx, 1, 1)
            pos[f"{side}_{f}1"] = b
            pos[f"{side}_{f}2"] = b + (sx * l2, -0.002, 0.0)
            pos[f"{side}_{f}3"] = b + (sx * (l2 + l3), -0.004, 0.0)
        t1 = wrist + np.array((0.025 * sx, -0.015, 0.025))
        pos[f"{side}_thumb1"] = t1
        pos[f"{side}_thumb2"] = t1 + (0.025 * sx, -0.008, 0.020)
        pos[f"{side}_thumb3"] = t1 + (0.050 * sx, -0.013, 0.030)
    return np.stack([pos[n] for n in SMPLX_JOINT_NAMES])


SMPLX_TEMPLATE_JOINTS = _template_joints()


@dataclass(frozen=True)
class SMPLXTake:
    """One SMPL-X parameter file: poses (T, J, 3) axis-angle (radians), trans (T, 3) metres,
    betas (B,) (empty when the file has none), fps, joints: the SMPL-X indices of the J joints."""

    path: str
    poses: np.ndarray
    trans: np.ndarray
    betas: np.ndarray
    fps: float
    joints: tuple[int, ...]

    @property
    def num_frames(self) -> int:
        return int(self.poses.shape[0])

    @property
    def duration(self) -> float:
        return self.num_frames / self.fps


def _open_npz(path: Path):
    if not path.is_file():
        raise MissingFileError("SMPL-X parameter file not found", path)
    try:
        return np.load(path, allow_pickle=False)
    except (zipfile.BadZipFile, ValueError, OSError, EOFError) as e:
        raise FormatError(f"not a readable .npz archive ({e})", path) from None


def _array(data, key: str, path: Path) -> np.ndarray:
    try:
        return np.asarray(data[key])
    except ValueError as e:  # an object array (needs pickle) or a damaged member
        raise FormatError(f"key {key!r} is not a plain numeric array ({e})", path, key) from None


def load_smplx_take(path: str | Path) -> SMPLXTake:
    """Read and check an SMPL-X/SMPL-H parameter ``.npz`` (keys ``poses``, ``trans``,
    ``mocap_frame_rate`` or ``mocap_framerate``; ``betas`` optional). Raises FormatError naming the
    file and the key or frame when the archive lacks a key, has the wrong shapes or non-finite values."""
    path = Path(path)
    data = _open_npz(path)
    with data:
        keys = set(data.files)
        missing = [k for k in ("poses", "trans") if k not in keys]
        rate_key = next((k for k in FRAME_RATE_KEYS if k in keys), None)
        if rate_key is None:
            missing.append("mocap_frame_rate")
        if missing:
            raise FormatError(f"not an SMPL-X parameter file: lacks {missing} (keys are {sorted(keys)}; "
                              f"expected poses (T, 165), trans (T, 3), mocap_frame_rate)", path)
        poses = _array(data, "poses", path)
        trans = _array(data, "trans", path)
        rate = _array(data, rate_key, path)
        betas = _array(data, "betas", path) if "betas" in keys else np.zeros(0)
    if poses.ndim != 2 or poses.shape[1] not in {3 * n for n in JOINT_SETS} or poses.shape[0] == 0:
        raise FormatError(f"poses has shape {poses.shape}, expected (T, 165) (SMPL-X), (T, 156) (SMPL-H) "
                          "or (T, 66) (body) with T >= 1", path, "poses")
    if trans.shape != (poses.shape[0], 3):
        raise FormatError(f"trans has shape {trans.shape}, expected ({poses.shape[0]}, 3) (one row per "
                          "frame of poses)", path, "trans")
    for key, arr in (("poses", poses), ("trans", trans)):
        if not np.issubdtype(arr.dtype, np.number):
            raise FormatError(f"{key} holds {arr.dtype} values, expected numbers", path, key)
        bad = np.argwhere(~np.isfinite(arr))
        if bad.size:
            raise FormatError(f"non-finite value at frame {bad[0][0]}, column {bad[0][1]}", path, key)
    try:
        fps = float(np.reshape(rate, -1)[0])
    except (IndexError, TypeError, ValueError):
        fps = float("nan")
    if not (np.isfinite(fps) and fps > 0):
        raise FormatError(f"{rate_key} must be a positive number, got {rate!r}", path, rate_key)
    betas = np.reshape(betas, -1)
    if betas.size and (not np.issubdtype(betas.dtype, np.number) or not np.all(np.isfinite(betas))):
        raise FormatError("betas must be finite numbers", path, "betas")
    J = poses.shape[1] // 3
    return SMPLXTake(str(path), poses.astype(np.float64).reshape(-1, J, 3), trans.astype(np.float64),
                     betas.astype(np.float64), fps, JOINT_SETS[J])


def smplx_duration(path: str | Path) -> float:
    """Seconds of an SMPL-X parameter file (its frames / mocap_frame_rate)."""
    return load_smplx_take(path).duration


def load_smplx_model(path: str | Path) -> dict:
    """``J_regressor`` (J, V), ``v_template`` (V, 3), ``shapedirs`` (V, 3, S) of an SMPL-X model file
    (the official ``SMPLX_*.npz`` or ``.pkl``), as float64 arrays. Raises FormatError naming the file
    when it is not a model file of that kind (missing keys, inconsistent shapes)."""
    path = Path(path)
    if not path.is_file():
        raise MissingFileError("SMPL-X model file not found", path)
    if path.suffix.lower() == ".npz":
        data = _open_npz(path)
        with data:
            missing = [k for k in MODEL_KEYS if k not in data.files]
            if missing:
                raise FormatError(f"not an SMPL-X model file: lacks {missing} (keys are {sorted(data.files)})", path)
            model = {k: _array(data, k, path) for k in MODEL_KEYS}
    elif path.suffix.lower() == ".pkl":
        try:
            with open(path, "rb") as fh:
                raw = pickle.load(fh, encoding="latin1")
        except ModuleNotFoundError as e:
            raise FormatError(f"the pickle needs the module {e.name!r} (an SMPL model pickled with chumpy?); "
                              "use the SMPL-X .npz model file instead", path) from None
        except Exception as e:  # noqa: BLE001 - a damaged or foreign pickle can raise anything
            raise FormatError(f"not a readable pickle ({type(e).__name__}: {e})", path) from None
        if not isinstance(raw, dict) or any(k not in raw for k in MODEL_KEYS):
            keys = sorted(raw) if isinstance(raw, dict) else type(raw).__name__
            raise FormatError(f"not an SMPL-X model file: expected keys {list(MODEL_KEYS)}, found {keys}", path)
        model = {}
        for k in MODEL_KEYS:
            v = raw[k]
            model[k] = np.asarray(v.toarray() if hasattr(v, "toarray") else v)
    else:
        raise FormatError("an SMPL-X model file must be .npz or .pkl", path)
    try:
        model = {k: np.asarray(v, dtype=np.float64) for k, v in model.items()}
    except (TypeError, ValueError) as e:
        raise FormatError(f"model arrays are not numeric ({e})", path) from None
    jr, vt, sd = model["J_regressor"], model["v_template"], model["shapedirs"]
    if vt.ndim != 2 or vt.shape[1] != 3:
        raise FormatError(f"v_template has shape {vt.shape}, expected (V, 3)", path, "v_template")
    V = vt.shape[0]
    if jr.ndim != 2 or jr.shape[1] != V:
        raise FormatError(f"J_regressor has shape {jr.shape}, expected (J, {V}) for {V} template vertices",
                          path, "J_regressor")
    if sd.ndim != 3 or sd.shape[:2] != (V, 3):
        raise FormatError(f"shapedirs has shape {sd.shape}, expected ({V}, 3, S)", path, "shapedirs")
    return model


def smplx_rest_joints(betas=None, model_path: str | Path | None = None, num_joints: int = 55) -> np.ndarray:
    """(num_joints, 3) rest joint positions in metres: exact from ``model_path`` with ``betas``
    (the first min(len(betas), S) shape directions; SMPL-X's later directions are expressions), else
    the generic :data:`SMPLX_TEMPLATE_JOINTS` (approximate; betas ignored)."""
    if model_path is None:
        return SMPLX_TEMPLATE_JOINTS[:num_joints].copy()
    model = load_smplx_model(model_path)
    jr, vt, sd = model["J_regressor"], model["v_template"], model["shapedirs"]
    if jr.shape[0] < num_joints:
        raise FormatError(f"J_regressor regresses {jr.shape[0]} joints, the take needs {num_joints} "
                          "(an SMPL or SMPL-H model file? expected SMPL-X)", model_path, "J_regressor")
    b = np.reshape(np.asarray(betas if betas is not None else [], dtype=np.float64), -1)
    n = min(b.size, sd.shape[2])
    shaped = vt + (sd[:, :, :n] @ b[:n] if n else 0.0)
    return jr[:num_joints] @ shaped


def smplx_skeleton(rest_joints: np.ndarray, joints: tuple[int, ...] = tuple(range(55))) -> Skeleton:
    """The BVH skeleton of SMPL-X joints ``joints`` (indices of :data:`SMPLX_JOINT_NAMES`, parents
    before children) with rest joints (len(joints), 3) in metres: offsets J_j - J_parent in cm."""
    rest = np.asarray(rest_joints, dtype=np.float64) * CM_PER_M
    index = {j: k for k, j in enumerate(joints)}
    parents = tuple(index[SMPLX_PARENTS[j]] if SMPLX_PARENTS[j] >= 0 else -1 for j in joints)
    offsets = np.array([rest[k] - (rest[p] if p >= 0 else 0.0) for k, p in enumerate(parents)])
    ends = []
    for k in range(len(joints)):
        if k not in parents and parents[k] >= 0:   # a leaf: an End Site half its bone on
            ends.append((k, tuple(float(x) for x in 0.5 * offsets[k])))
    return Skeleton(tuple(SMPLX_JOINT_NAMES[j] for j in joints), parents, offsets,
                    tuple(ROOT_CHANNELS if p < 0 else JOINT_CHANNELS for p in parents), tuple(ends))


def axis_angle_to_quat_np(rotvec) -> np.ndarray:
    """(..., 3) axis-angle (radians) -> (..., 4) unit quaternions (w, x, y, z), float64, through
    :func:`convsynth_jax.rotations.axis_angle_to_quat` (the zero vector gives the identity)."""
    v = np.asarray(rotvec, dtype=np.float64)
    angle = np.linalg.norm(v, axis=-1)
    axis = v / np.where(angle > 0, angle, 1.0)[..., None]
    q = np.asarray(axis_angle_to_quat(axis, angle), dtype=np.float64)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def smplx_motion(path: str | Path, fps: float | None = 30, smplx_model: str | Path | None = None) -> Motion:
    """An SMPL-X parameter file as a :class:`Motion` in centimetres (SMPL-X joint names, root at
    ``(trans + J_0) * 100``), resampled to ``fps`` unless None. ``smplx_model``: the user's SMPL-X
    model file for exact rest joints (else the approximate template)."""
    take = load_smplx_take(path)
    rest = smplx_rest_joints(take.betas, smplx_model, 55)[list(take.joints)]
    skel = smplx_skeleton(rest, take.joints)
    rotations = axis_angle_to_quat_np(take.poses)
    translations = np.broadcast_to(skel.offsets, (take.num_frames,) + skel.offsets.shape).copy()
    translations[:, 0] = (take.trans + rest[0]) * CM_PER_M
    motion = Motion(skel, rotations, translations, take.fps, str(path))
    return motion.resample(fps) if fps is not None else motion
