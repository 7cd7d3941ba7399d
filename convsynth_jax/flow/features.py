"""What the flow-matching model reads and writes, per frame at the model's frame rate.

Motion: every joint's local rotation in the continuous 6-D form (the first two columns of its
rotation matrix, Zhou et al. 2019), the root's with the recording's mean heading removed, plus the
root's position (the horizontal offset from the recording's mean position in that heading frame,
and the height). Decoding places the character at a chair (position, heading) instead, so the model
never learns where a recording's chair stood.

Audio: per channel (the speaker's own and the partner's), 16 log-mel bands, log RMS energy, the
onset strength (librosa's spectral flux on the log-mel, the same detector family the field's beat
consistency uses) and the log spectral centroid, pooled onto the model's frames (mean; the onset
strength by maximum, so a short onset is not averaged away). No transcript is needed.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..rotations import quat_multiply_np, quat_to_matrix_np, rotate_about_y_np, yaw_angle_np, yaw_to_quat_np
from ..skeleton import Motion

N_MELS = 16
AUDIO_NAMES = tuple(f"mel{i}" for i in range(N_MELS)) + ("log_energy", "onset_strength", "log_centroid")
AUDIO_DIM = len(AUDIO_NAMES)
ROOT_DIM = 3


def motion_dim(num_joints: int) -> int:
    """Values per frame of :func:`encode_motion`: 6 per joint plus the root position."""
    return 6 * int(num_joints) + ROOT_DIM


def mean_heading(q_root: np.ndarray) -> float:
    """Circular mean (radians) of the root's heading over a recording."""
    y = yaw_angle_np(q_root)
    return float(np.arctan2(np.sin(y).mean(), np.cos(y).mean()))


def encode_motion(motion: Motion) -> np.ndarray:
    """(F, 6 J + 3) float32 features of ``motion`` (module docstring)."""
    rot = np.asarray(motion.rotations, np.float64)
    heading = mean_heading(rot[:, 0])
    rot = rot.copy()
    rot[:, 0] = quat_multiply_np(yaw_to_quat_np(-heading), rot[:, 0])
    six = quat_to_matrix_np(rot)[..., :, :2].reshape(len(rot), -1)
    p = np.asarray(motion.translations[:, 0], np.float64)
    off = rotate_about_y_np(p - p.mean(axis=0), -heading)
    root = np.stack([off[:, 0], p[:, 1], off[:, 2]], axis=1)
    return np.concatenate([six, root], axis=1).astype(np.float32)


def six_to_quat(six: np.ndarray) -> np.ndarray:
    """(..., 6) -> (..., 4) (w, x, y, z) unit quaternions by Gram-Schmidt on the two columns."""
    from scipy.spatial.transform import Rotation

    m = np.asarray(six, np.float64).reshape(six.shape[:-1] + (3, 2))
    a1, a2 = m[..., 0], m[..., 1]
    b1 = a1 / np.maximum(np.linalg.norm(a1, axis=-1, keepdims=True), 1e-9)
    a2 = a2 - np.sum(b1 * a2, axis=-1, keepdims=True) * b1
    b2 = a2 / np.maximum(np.linalg.norm(a2, axis=-1, keepdims=True), 1e-9)
    b3 = np.cross(b1, b2)
    mat = np.stack([b1, b2, b3], axis=-1)
    q = Rotation.from_matrix(mat.reshape(-1, 3, 3)).as_quat()
    return q[:, [3, 0, 1, 2]].reshape(six.shape[:-1] + (4,))   # SciPy's (x, y, z, w) -> (w, x, y, z)


def decode_motion(x: np.ndarray, template: Motion, fps: float, chair=(0.0, 0.0, 0.0), chair_yaw_deg: float = 0.0,
                  name: str = "flow_matching") -> Motion:
    """The Motion of features ``x`` (F, 6 J + 3) on ``template``'s skeleton (its non-root joint
    translations, the rest offsets), the root placed at ``chair`` facing ``chair_yaw_deg``."""
    x = np.asarray(x, np.float64)
    J = template.skeleton.num_joints
    if x.ndim != 2 or x.shape[1] != motion_dim(J):
        raise ConfigError(f"flow_matching: features of shape {x.shape} do not fit a {J}-joint skeleton "
                          f"({motion_dim(J)} values per frame)")
    F = len(x)
    q = six_to_quat(x[:, :6 * J].reshape(F, J, 6))
    yaw = np.deg2rad(float(chair_yaw_deg))
    q[:, 0] = quat_multiply_np(yaw_to_quat_np(np.full(F, yaw)), q[:, 0])
    trans = np.repeat(np.asarray(template.translations[:1], np.float64), F, axis=0)
    root = x[:, 6 * J:]
    off = rotate_about_y_np(np.stack([root[:, 0], np.zeros(F), root[:, 2]], axis=1), yaw)
    trans[:, 0] = np.asarray(chair, np.float64) + off
    trans[:, 0, 1] = root[:, 1]
    return Motion(template.skeleton, q, trans, float(fps), name)


def resample_features(x: np.ndarray, n_out: int, ratio: float) -> np.ndarray:
    """(F, D) -> (n_out, D) by linear interpolation: output frame j lies at input frame j * ratio
    (``ratio`` = input rate / output rate); past the last input frame the last value is held."""
    x = np.asarray(x, np.float64)
    src = np.arange(len(x), dtype=np.float64)
    dst = np.arange(int(n_out), dtype=np.float64) * float(ratio)
    return np.stack([np.interp(dst, src, x[:, d]) for d in range(x.shape[1])], axis=1)


@dataclass(frozen=True)
class Standardizer:
    """Per-dimension z-normalisation fitted on training frames (a dimension that hardly moves keeps
    its SD floored, so it is not blown up)."""

    mean: np.ndarray
    std: np.ndarray

    @staticmethod
    def fit(x: np.ndarray, floor: float = 1e-2) -> "Standardizer":
        x = np.asarray(x, np.float64)
        return Standardizer(x.mean(axis=0).astype(np.float32), np.maximum(x.std(axis=0), floor).astype(np.float32))

    def apply(self, x):
        return ((np.asarray(x, np.float32) - self.mean) / self.std).astype(np.float32)

    def invert(self, x):
        return np.asarray(x, np.float64) * self.std + self.mean


def frame_detail_sd(x: np.ndarray) -> np.ndarray:
    """(D,) SD of the white frame-to-frame detail of features ``x`` (F, D) at their own rate (sensor
    noise and the finest motion the model's rate and principal components leave out): from the second
    difference, whose variance is 6 sigma^2 for white noise, robustly (1.4826 x its median absolute
    value, so gestures' accelerations hardly count)."""
    d2 = np.diff(np.asarray(x, np.float64), n=2, axis=0)
    if len(d2) == 0:
        return np.zeros(np.asarray(x).shape[1])
    return 1.4826 * np.median(np.abs(d2), axis=0) / np.sqrt(6.0)


ROOT_SCALE = 0.05   # root position units (cm in the synthetic corpus) per unit of the 6-D rotation values


@dataclass(frozen=True)
class MotionBasis:
    """Whitened principal components of the training motion features (the root position scaled by
    ``ROOT_SCALE`` so centimetres and rotation-matrix entries weigh alike), keeping the fewest
    components that explain ``variance`` of it (at most ``max_components``): the model's space. The
    dropped directions (sensor noise, joints that never move) are left at the training mean."""

    mean: np.ndarray        # (D,)
    scale: np.ndarray       # (D,) per-feature factor applied before the projection
    components: np.ndarray  # (K, D) orthonormal rows
    sd: np.ndarray          # (K,) SD along each component

    @staticmethod
    def fit(x: np.ndarray, variance: float = 0.995, max_components: int = 64) -> "MotionBasis":
        x = np.asarray(x, np.float64)
        scale = np.ones(x.shape[1])
        scale[-ROOT_DIM:] = ROOT_SCALE
        mean = x.mean(axis=0)
        y = (x - mean) * scale
        _, s, vt = np.linalg.svd(y, full_matrices=False)
        var = s ** 2 / max(len(y) - 1, 1)
        k = int(np.searchsorted(np.cumsum(var) / max(var.sum(), 1e-300), variance) + 1)
        k = max(1, min(k, int(max_components), len(var)))
        return MotionBasis(mean.astype(np.float32), scale.astype(np.float32), vt[:k].astype(np.float32),
                           np.sqrt(np.maximum(var[:k], 1e-12)).astype(np.float32))

    @property
    def dim(self) -> int:
        return int(self.components.shape[0])

    def apply(self, x):
        y = (np.asarray(x, np.float64) - self.mean) * self.scale
        return (y @ self.components.T.astype(np.float64) / self.sd).astype(np.float32)

    def invert(self, z):
        y = (np.asarray(z, np.float64) * self.sd) @ self.components.astype(np.float64)
        return y / self.scale + self.mean


def _mono(samples: np.ndarray) -> np.ndarray:
    x = np.asarray(samples, np.float32)
    return x.mean(axis=1) if x.ndim > 1 else x


def audio_features(audio, num_frames: int, fps: float) -> np.ndarray:
    """(num_frames, AUDIO_DIM) float32 features of ``audio`` (an ``io.Audio``) at ``fps``; frames
    past the audio's end (or no audio: None) are silence (every value at its floor)."""
    out = np.zeros((int(num_frames), AUDIO_DIM), np.float32)
    floor = np.log(1e-5)
    out[:, :N_MELS] = floor
    out[:, N_MELS] = floor
    out[:, N_MELS + 2] = np.log(1.0)
    if audio is None or num_frames <= 0:
        return out
    import librosa

    x = _mono(audio.samples)
    sr = int(audio.sample_rate)
    hop = 256
    if len(x) < 2048:
        return out
    mel = librosa.feature.melspectrogram(y=x, sr=sr, n_fft=1024, hop_length=hop, n_mels=N_MELS, fmax=min(8000, sr / 2))
    logmel = np.log(np.maximum(mel, 1e-5))
    onset = librosa.onset.onset_strength(S=librosa.power_to_db(mel), sr=sr, hop_length=hop)
    rms = librosa.feature.rms(y=x, frame_length=1024, hop_length=hop)[0]
    cent = librosa.feature.spectral_centroid(y=x, sr=sr, n_fft=1024, hop_length=hop)[0]
    n = min(logmel.shape[1], len(onset), len(rms), len(cent))
    t = np.arange(n) * hop / sr
    idx = np.round(t * fps).astype(np.int64)
    keep = idx < num_frames
    idx = idx[keep]
    feats = np.concatenate([logmel[:, :n].T, np.log(np.maximum(rms[:n], 1e-5))[:, None],
                            np.zeros((n, 1)), np.log(np.maximum(cent[:n], 1.0))[:, None]], axis=1)[keep]
    sums = np.zeros((num_frames, AUDIO_DIM))
    counts = np.zeros(num_frames)
    np.add.at(sums, idx, feats)
    np.add.at(counts, idx, 1.0)
    peak = np.zeros(num_frames)
    np.maximum.at(peak, idx, onset[:n][keep])
    have = counts > 0
    out[have] = (sums[have] / counts[have, None]).astype(np.float32)
    out[have, N_MELS + 1] = peak[have]
    return out


def recording_audio_features(path: str, channel, fps: float) -> np.ndarray:
    """(F, AUDIO_DIM) features of a whole recording (computed once per process and file content:
    every fold and both characters reuse them, a file edited in place is read again); F covers the
    audio's duration."""
    from ..fingerprint import file_digest

    return _recording_audio_features(str(path), channel, float(fps), file_digest(path))


@functools.lru_cache(maxsize=128)
def _recording_audio_features(path: str, channel, fps: float, content: str) -> np.ndarray:
    """:func:`recording_audio_features` remembered by (path, channel, rate, the file's digest)."""
    from ..io import load_audio

    a = load_audio(path, channel=channel)
    return audio_features(a, int(np.floor(a.duration * fps)), fps)


def fit_length(x: np.ndarray, n: int) -> np.ndarray:
    """Audio features ``x`` (F, AUDIO_DIM) cut or padded with silence to n rows."""
    x = np.asarray(x, np.float32)
    if len(x) >= n:
        return x[:n]
    return np.concatenate([x, audio_features(None, n - len(x), 1.0)])
