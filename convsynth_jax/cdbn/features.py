"""Features of the CDBN (Sec. IV-C): prosody (F0, energy and their first and second derivatives,
6-D, 40 ms windows every 16.67 ms, unvoiced F0 interpolated) and head rotation (pitch, yaw, roll),
both z-normalized per subject and brought to the model frame rate; per-frame constraint codes from
TSV rows (start, end, label).

Our choices: F0 from Praat's autocorrelation tracker (parselmouth) whose analysis window is three
periods of the floor (75 Hz -> the paper's 40 ms); ``f0_floor='auto'`` adapts floor and ceiling to
the speaker (two passes, De Looze & Hirst: 0.72 q35 / 1.9 q65 of a 60-700 Hz pass). Energy is the
log RMS (dB) of 40 ms Hann windows. Derivatives are central differences per second. The 60 fps
prosody is linearly interpolated onto the motion frame times (the paper up-samples to 120 fps; our
corpora run at 30 fps). Head rotation: the composed local rotation of ``head_joints`` (the neck then
the head, found by role through convsynth_jax.rig) as intrinsic Z-X-Y Euler angles in degrees, reported as (pitch = X, yaw = Y, roll = Z).
"""
from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation

from ..errors import CDBNError
from ..rig import resolve_joint
from .params import CDBNFeatureParams

SPEECH_NAMES = ("f0", "energy", "d_f0", "d_energy", "dd_f0", "dd_energy")
MOTION_NAMES = ("head_pitch", "head_yaw", "head_roll")
FEATURE_LAYOUT = SPEECH_NAMES + MOTION_NAMES


class Normalization(NamedTuple):
    """Per-subject z-normalization of one stream: mean (d,), sd (d,)."""

    mean: np.ndarray
    sd: np.ndarray

    def apply(self, x):
        return (np.asarray(x) - self.mean) / self.sd

    def invert(self, z):
        return np.asarray(z) * self.sd + self.mean

    @staticmethod
    def fit(x: np.ndarray) -> Normalization:
        x = np.asarray(x, np.float64)
        return Normalization(x.mean(0), np.maximum(x.std(0), 1e-6))


def _mono(audio) -> tuple[np.ndarray, float]:
    x = np.asarray(audio.samples, np.float64)
    if x.ndim > 1:
        x = x.mean(axis=1)
    return x, float(audio.sample_rate)


def _pitch(x, sr, step, floor, ceiling):
    import parselmouth

    snd = parselmouth.Sound(x, sampling_frequency=sr)
    p = snd.to_pitch(time_step=step, pitch_floor=floor, pitch_ceiling=ceiling)
    f0 = p.selected_array["frequency"].astype(np.float64)
    f0[f0 <= 0] = np.nan
    return np.asarray(p.xs(), np.float64), f0


def prosody_f0_track(audio, params: CDBNFeatureParams, path: str | Path | None = None) -> tuple[np.ndarray, np.ndarray, float]:
    """(times, f0 with NaN where unvoiced, floor used) at ``params.hop``."""
    x, sr = _mono(audio)
    if params.f0_floor == "auto":
        t, f = _pitch(x, sr, params.hop, 60.0, 700.0)
        v = f[np.isfinite(f)]
        floor, ceiling = 75.0, params.f0_ceiling
        if v.size >= 20:
            floor = max(40.0, 0.72 * float(np.percentile(v, 35)))
            ceiling = max(floor * 2.0, 1.9 * float(np.percentile(v, 65)))
    else:
        floor, ceiling = float(params.f0_floor), float(params.f0_ceiling)
    t, f = _pitch(x, sr, params.hop, floor, ceiling)
    return t, f, floor


def energy_track(audio, times: np.ndarray, window: float) -> np.ndarray:
    """Log RMS energy (dB) of Hann windows of ``window`` s centred at ``times``."""
    x, sr = _mono(audio)
    n = max(2, round(window * sr))
    w = np.hanning(n)
    centres = np.round(times * sr).astype(int)
    starts = np.clip(centres - n // 2, 0, max(len(x) - n, 0))
    idx = starts[:, None] + np.arange(n)[None, :]
    idx = np.clip(idx, 0, len(x) - 1)
    frames = x[idx] * w
    rms = np.sqrt(np.mean(frames ** 2, axis=1) / np.mean(w ** 2))
    return 20.0 * np.log10(rms + 1e-5)


def interpolate_unvoiced(f0: np.ndarray) -> np.ndarray:
    """Linear interpolation of F0 across unvoiced (NaN) frames, held constant at the edges."""
    v = np.isfinite(f0)
    t = np.arange(len(f0))
    return np.interp(t, t[v], f0[v])


def speech_features(audio, params: CDBNFeatureParams, num_frames: int | None = None, fps: float | None = None,
                    path: str | Path | None = None) -> np.ndarray:
    """Raw (un-normalized) prosody (F, 6): F0, energy, their first and second derivatives, at the
    model frame rate (``num_frames`` frames at ``fps``; default: the audio duration at params.fps)."""
    fps = float(fps or params.fps)
    where = str(path or getattr(audio, "path", "") or "audio")
    x, sr = _mono(audio)
    if len(x) < int(0.2 * sr):
        raise CDBNError(f"audio too short for prosody ({len(x) / sr:.3f} s)", where)
    t, f0, floor = prosody_f0_track(audio, params, path)
    voiced = np.isfinite(f0)
    if voiced.sum() < max(3, params.min_voiced_fraction * len(f0)):
        raise CDBNError(f"too few voiced frames for F0 ({int(voiced.sum())} of {len(f0)} at a {floor:.0f} Hz floor); "
                        f"a creaky or low voice may need a lower F0 floor, e.g. cdbn.features.f0_floor=40", where)
    f = interpolate_unvoiced(f0)
    e = energy_track(audio, t, params.window)
    d = np.stack([f, e], axis=1)
    d1 = np.gradient(d, params.hop, axis=0)
    d2 = np.gradient(d1, params.hop, axis=0)
    raw = np.concatenate([d, d1, d2], axis=1)
    n = int(num_frames) if num_frames is not None else round(len(x) / sr * fps)
    ft = np.arange(n) / fps
    out = np.stack([np.interp(ft, t, raw[:, k]) for k in range(6)], axis=1)
    check_finite(out, where, "speech features")
    return out


def check_finite(x: np.ndarray, where: str, what: str) -> None:
    bad = np.flatnonzero(~np.all(np.isfinite(x), axis=-1))
    if bad.size:
        raise CDBNError(f"{what} are not finite (NaN/inf) at frame {int(bad[0])} "
                        f"({bad.size} frames in all)", where, f"frame {int(bad[0])}")


def head_joint_indices(skel, head_joints, where: str = "") -> list[int]:
    """Joint indices of ``head_joints`` (cdbn.features.head_joints): each a role of
    :data:`convsynth_jax.rig.RIG_JOINTS`, an exact joint name, or a regex on the names; CDBNError
    naming the entry and the joints when one is not found."""
    out = []
    for name in head_joints:
        j = resolve_joint(skel, name)
        if j is None:
            j = skel.find(f"^{name}$", name)
        if j is None:
            raise CDBNError(f"skeleton has no joint matching {name!r} (cdbn.features.head_joints); "
                            f"joints are {list(skel.names)}", where)
        out.append(j)
    return out


def head_rotation(motion, params: CDBNFeatureParams) -> np.ndarray:
    """(F, 3) head pitch, yaw, roll in degrees: the composed local rotations of ``params.head_joints``."""
    q = None
    for j in head_joint_indices(motion.skeleton, params.head_joints, motion.name):
        r = Rotation.from_quat(np.asarray(motion.rotations[:, j])[:, [1, 2, 3, 0]])
        q = r if q is None else q * r
    zxy = q.as_euler("ZXY", degrees=True)
    return np.stack([zxy[:, 1], zxy[:, 2], zxy[:, 0]], axis=1)


def head_euler_to_quat(angles: np.ndarray) -> np.ndarray:
    """(F, 3) pitch, yaw, roll degrees -> (F, 4) quaternions (w, x, y, z) of the composed head rotation."""
    r = Rotation.from_euler("ZXY", np.stack([angles[:, 2], angles[:, 0], angles[:, 1]], axis=1), degrees=True)
    return r.as_quat()[:, [3, 0, 1, 2]]


def check_lengths(speech: np.ndarray, motion: np.ndarray, speech_path, motion_path) -> int:
    """Common frame count; CDBNError naming both files when they differ by more than one frame."""
    if abs(len(speech) - len(motion)) > 1:
        raise CDBNError(f"speech has {len(speech)} frames ({speech_path}) but motion has {len(motion)} frames "
                        f"({motion_path}); they may differ by at most one frame", speech_path)
    return min(len(speech), len(motion))


def read_constraints(path: str | Path, names: tuple, num_frames: int, fps: float, default: str = "other") -> np.ndarray:
    """Per-frame constraint codes (F,) from a TSV of rows ``start end label`` (seconds; optional header).
    Frames no row covers get ``default``. Unknown labels and overlapping rows raise CDBNError naming
    the line."""
    path = Path(path)
    if not path.is_file():
        raise CDBNError("constraint file not found", path)
    names = tuple(names)
    codes = np.full(num_frames, names.index(default) if default in names else 0, np.int32)
    rows = []
    for lineno, line in enumerate(path.read_text().splitlines(), start=1):
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        parts = s.split("\t") if "\t" in s else s.split()
        if lineno == 1 and parts[0].lower() == "start":
            continue
        if len(parts) < 3:
            raise CDBNError(f"expected 'start<TAB>end<TAB>label', got {line!r}", path, f"line {lineno}")
        try:
            a, b = float(parts[0]), float(parts[1])
        except ValueError:
            raise CDBNError(f"start/end are not numbers: {line!r}", path, f"line {lineno}") from None
        label = parts[2].strip()
        if label not in names:
            raise CDBNError(f"unknown constraint label {label!r}; known labels are {list(names)}", path,
                            f"line {lineno}")
        if not (np.isfinite(a) and np.isfinite(b) and b > a >= 0):
            raise CDBNError(f"need 0 <= start < end, got {a}, {b}", path, f"line {lineno}")
        for (a0, b0, l0) in rows:
            if a < b0 and a0 < b:
                raise CDBNError(f"row {a}-{b} {label!r} overlaps the row at line {l0} ({a0}-{b0})", path,
                                f"line {lineno}")
        rows.append((a, b, lineno))
        codes[round(a * fps):round(b * fps)] = names.index(label)
    return codes


def constraints_table(codes: np.ndarray, names: tuple, fps: float) -> pd.DataFrame:
    """Per-frame codes -> DataFrame[start, end, label] of runs (seconds)."""
    codes = np.asarray(codes)
    edges = np.flatnonzero(np.diff(codes)) + 1
    starts = np.concatenate([[0], edges])
    ends = np.concatenate([edges, [len(codes)]])
    return pd.DataFrame({"start": starts / fps, "end": ends / fps, "label": [names[codes[s]] for s in starts]})


def head_rotation_from_quat(q: np.ndarray) -> np.ndarray:
    """(F, 4) composed head quaternions (w, x, y, z) -> (F, 3) pitch, yaw, roll degrees."""
    zxy = Rotation.from_quat(np.asarray(q)[:, [1, 2, 3, 0]]).as_euler("ZXY", degrees=True)
    return np.stack([zxy[:, 1], zxy[:, 2], zxy[:, 0]], axis=1)
