"""A large motion database for scaling benchmarks (ours; ``convsynth task=make_scale_db``).

Assembled, reproducibly from a seed, out of
* the real Bandai-Namco clips (``bandai_root``; skipped when the folder is absent: synthetic only),
* sessions of the synthetic conversation corpus (data/synthetic: motion rendered from each
  session's plan, both participants; own and partner audio status from the planted segments),
and seeded variants of every clip: mirrored (left and right swapped), time-warped (a constant speed
factor drawn per clip, resampled by linear interpolation) with small smooth pose noise, and both.

The rigs differ (Bandai's 22 joints, the synthetic corpus's seated 28), so every clip is reduced to
the body roles that all its rigs have (rig.py: hips, spine, neck, head, collars, shoulders, elbows,
hands, legs, feet found by name), in root-relative positions (heading removed, Y up) and their
per-clip velocities (central differences, as kinematics.batched_pose_features). The variants are
made on these features: a mirror negates the lateral (X) axis and swaps left and right roles; noise
and warps act on positions and the velocities are differenced again.

Order: originals first (Bandai, then synthetic sessions in order), then each variant kind over the
same clips; the last clip is cut so that the database has exactly ``frames`` frames. The same
arguments give the same arrays (tests/test_scale_db.py).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..annotate.types import FrameAudio
from ..errors import ConfigError, GraphError
from ..kinematics import batched_pose_features
from ..rig import find_role
from .database import MotionDatabase

log = logging.getLogger(__name__)

# body roles looked up in every rig (left/right pairs are swapped by a mirror)
ROLES = ("hips", "spine", "neck", "head", "left_collar", "right_collar", "left_shoulder", "right_shoulder",
         "left_elbow", "right_elbow", "left_hand", "right_hand", "left_upleg", "right_upleg", "left_foot",
         "right_foot")
LATERAL_AXIS = 0  # X: the side axis of the root-relative frame (Y up, heading removed)
VARIANTS = ("original", "mirror", "warp", "mirror_warp")


@dataclass(frozen=True)
class ScaleDBParams:
    frames: int = 1_000_000
    seed: int = 0
    bandai_root: str | None = None         # folder of Bandai BVH files (None or missing: synthetic only)
    session_seconds: float = 106.0         # length of each synthetic session
    warp_range: tuple = (0.8, 1.25)        # speed factors of the time-warped variants
    noise_cm: float = 0.5                  # sd of the smooth pose noise of the warped variants (cm)
    noise_seconds: float = 0.3             # its smoothing time scale
    calibrate: bool = True                 # the synthetic corpus's planting-rate calibration (about 16 s)
    fps: float = 30.0

    def __post_init__(self):
        if int(self.frames) < 1:
            raise ConfigError(f"frames must be >= 1, got {self.frames}", where="task.frames")
        lo, hi = self.warp_range
        if not 0 < lo <= hi:
            raise ConfigError(f"warp_range must be 0 < lo <= hi, got {self.warp_range}", where="task.warp_range")


@dataclass
class _Clip:
    name: str
    P: np.ndarray         # (n, R, 3) root-relative positions of the roles
    own: FrameAudio
    partner: FrameAudio
    segments: tuple = ((), ())  # own, partner: (kind, start, end, peak) seconds (synthetic clips)


def _role_index(skeleton) -> np.ndarray:
    idx = [find_role(skeleton, r) for r in ROLES]
    if any(i is None for i in idx):
        missing = [r for r, i in zip(ROLES, idx) if i is None]
        raise GraphError(f"rig without the roles {missing} (joints: {skeleton.names[:6]}...)")
    return np.asarray(idx)


def _velocities(P: np.ndarray, fps: float) -> np.ndarray:
    return (np.gradient(P, axis=0) * fps).astype(np.float32) if len(P) > 1 else np.zeros_like(P)


def _idle(n: int) -> FrameAudio:
    return FrameAudio(np.zeros(n, np.int8), *(np.full(n, -1, np.int32) for _ in range(3)))


def _audio(segs, n: int, fps: float) -> FrameAudio:
    import pandas as pd

    df = pd.DataFrame(list(segs), columns=["kind", "start", "end", "peak"])
    return FrameAudio.from_segments(df, n, fps)


def bandai_clips(root, fps: float) -> list[_Clip]:
    """The real clips (roles' root-relative positions, idle audio), or [] without the folder."""
    from .database import bvh_folder_clips

    root = Path(root) if root else None
    if root is None or not root.is_dir() or not any(root.glob("**/*.bvh")):
        log.info("no Bandai clips at %s: synthetic motion only", root)
        return []
    clips = bvh_folder_clips(root, fps=fps)
    motions = [c[1] for c in clips]
    P, _ = batched_pose_features(motions, 1, True)
    idx = _role_index(motions[0].skeleton)
    out, s = [], 0
    for name, m, _, _ in clips:
        n = m.num_frames
        out.append(_Clip(f"bandai/{name}", P[s:s + n][:, idx], _idle(n), _idle(n)))
        s += n
    return out


def synthetic_clips(num_sessions: int, seed: int, session_seconds: float, fps: float, calibrate: bool = True) -> list[_Clip]:
    """Both participants of ``num_sessions`` synthetic sessions (motion and planted audio status).
    ``calibrate``: the corpus's planting-rate calibration (run on at most the default corpus's 17
    sessions: it takes about 16 s); False plants with the configured rates."""
    from ..data.synthetic import ROLES as PARTS
    from ..data.synthetic import _plan, _quota_offsets, _render_motion, planting_probabilities, resolve_config

    cfg = resolve_config({"seed": int(seed), "num_sessions": int(num_sessions), "session_seconds": float(session_seconds),
                          "fps": int(round(fps)), "calibrate_rates": bool(calibrate)})
    probs, _ = planting_probabilities({**cfg, "num_sessions": min(int(num_sessions), 17)})
    offsets = _quota_offsets(cfg)
    out = []
    for i in range(int(num_sessions)):
        plan = _plan(i, cfg, probs, offsets)
        motions = [_render_motion(plan, role, cfg)[0] for role in PARTS]
        P, _ = batched_pose_features(motions, 1, True)
        idx = _role_index(motions[0].skeleton)
        s = 0
        for role, m in zip(PARTS, motions):
            n = m.num_frames
            segs = {r: [(g.kind, g.start, g.end, g.peak) for g in plan["segs"] if g.role == r] for r in PARTS}
            own, partner = segs[role], segs[PARTS[1 - PARTS.index(role)]]
            out.append(_Clip(f"synthetic/s{seed}_{plan['name']}_{role}", P[s:s + n][:, idx],
                             _audio(own, n, fps), _audio(partner, n, fps), (tuple(own), tuple(partner))))
            s += n
    return out


def _smooth_noise(rng, n: int, sd: float, frames: float) -> np.ndarray:
    """(n, R, 3) Gaussian noise smoothed by a moving average of ``frames`` frames, sd ``sd``."""
    w = max(1, int(round(frames)))
    raw = rng.normal(0.0, 1.0, (n + w - 1, len(ROLES), 3))
    c = np.cumsum(np.concatenate([np.zeros((1, len(ROLES), 3)), raw]), 0)
    return ((c[w:] - c[:-w]) / np.sqrt(w) * sd)[:n]


_MIRROR = np.asarray([ROLES.index(r.replace("left", "#").replace("right", "left").replace("#", "right"))
                      for r in ROLES])


def variant(clip: _Clip, kind: str, rng, params: ScaleDBParams) -> _Clip:
    """One seeded variant of a clip (``VARIANTS``)."""
    P, fps = clip.P.astype(np.float64), float(params.fps)
    own, partner, segs = clip.own, clip.partner, clip.segments
    if "mirror" in kind:
        P = P[:, _MIRROR].copy()
        P[..., LATERAL_AXIS] *= -1
    if "warp" in kind:
        s = float(rng.uniform(*params.warp_range))
        n = len(P)
        m = max(2, int(np.floor((n - 1) / s)) + 1)
        t = np.minimum(np.arange(m) * s, n - 1)
        i0 = np.floor(t).astype(np.int64)
        i1 = np.minimum(i0 + 1, n - 1)
        f = (t - i0)[:, None, None]
        P = P[i0] * (1 - f) + P[i1] * f
        P = P + _smooth_noise(rng, m, params.noise_cm, params.noise_seconds * fps)
        warp = lambda ss: tuple((k, a / s, b / s, c / s) for k, a, b, c in ss)  # noqa: E731
        segs = (warp(segs[0]), warp(segs[1]))
        own = _audio(segs[0], m, fps) if segs[0] else _idle(m)
        partner = _audio(segs[1], m, fps) if segs[1] else _idle(m)
    return _Clip(f"{clip.name}#{kind}", P.astype(np.float32), own, partner, segs)


def _cut(clip: _Clip, n: int) -> _Clip:
    if n >= len(clip.P):
        return clip
    return _Clip(clip.name, clip.P[:n], clip.own.slice(0, n), clip.partner.slice(0, n), clip.segments)


def make_scale_database(params: ScaleDBParams) -> MotionDatabase:
    """The database of exactly ``params.frames`` frames (see the module docstring)."""
    p = params
    base = bandai_clips(p.bandai_root, p.fps) if p.bandai_root else []
    base_frames = sum(len(c.P) for c in base)
    per_session = 2 * int(round(p.session_seconds * p.fps))
    # the warps change lengths (speed factors of mean length about 1): a 10% margin of originals
    need = max(0, int(np.ceil(1.1 * p.frames / len(VARIANTS))) - base_frames)
    n_sessions = max(1, int(np.ceil(need / per_session))) if need > 0 or not base else 0
    base = base + (synthetic_clips(n_sessions, p.seed, p.session_seconds, p.fps, p.calibrate) if n_sessions else [])
    clips, total = [], 0
    for k, kind in enumerate(VARIANTS):
        for c, clip in enumerate(base):
            if total >= p.frames:
                break
            v = clip if kind == "original" else variant(clip, kind, np.random.default_rng([int(p.seed), c, k]), p)
            v = _cut(v, int(p.frames) - total)
            clips.append(v)
            total += len(v.P)
    if total < p.frames:
        raise GraphError(f"could only assemble {total} of {p.frames} frames")
    lengths = [len(c.P) for c in clips]
    P = np.concatenate([c.P for c in clips]).astype(np.float32)
    V = np.concatenate([_velocities(c.P, p.fps) for c in clips])
    cat = lambda side, k: np.concatenate([getattr(getattr(c, side), k) for c in clips])  # noqa: E731
    fa = lambda side: FrameAudio(*(cat(side, k) for k in ("label", "seg_start", "seg_end", "seg_peak")))  # noqa: E731
    clip = np.repeat(np.arange(len(clips), dtype=np.int32), lengths)
    frame = np.concatenate([np.arange(n, dtype=np.int32) for n in lengths])
    weights = np.ones(len(ROLES), np.float32)
    meta = {"remove_yaw": True, "up_axis": 1, "root_relative": "positions minus root position, rotated by the "
            "inverse root heading", "scale_db": {"frames": int(p.frames), "seed": int(p.seed),
                                                 "bandai_frames": int(base_frames), "synthetic_sessions": int(n_sessions),
                                                 "variants": list(VARIANTS)}}
    return MotionDatabase(tuple(c.name for c in clips), float(p.fps), P, V, weights, clip, frame,
                          np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64), fa("own"), fa("partner"),
                          ROLES, meta, joint_turn=None)

