"""Gestures taken from the core system's synthesized conversation (ours, beyond the paper).

``convsynth task=synthesize`` writes one BVH per character of a dyadic conversation (motion-graph
output, on the corpus's seated skeleton). :func:`synthesized_gestures` turns such a file into
standing gesture clips on the locomotion library's rig, so the demo can make that conversation walk:

1. **Segmentation** with the project's hand-gesture measure (``annotate.motion``): the hand speeds
   relative to the shoulder (``joint_speeds``) and the recording's Eq. 1 idle threshold
   (``recording_thresholds``); a movement is a run of frames where either hand is faster than its
   threshold (runs closer than ``merge_s`` merged, shorter than ``min_s`` dropped, longer than
   ``max_s`` split at their slowest frame: a synthesized speaker seldom comes fully to rest), cut
   out with ``pad_s`` more on both sides.
2. **Retargeting by joint role** (both rigs found through ``convsynth_jax.rig.RIG_JOINTS``): each
   clip's upper-arm and forearm directions, expressed in a torso frame built from the hips, neck
   and the two upper-arm joints, are given to the target rig in its own torso frame. The target's
   collars, hands, torso and legs keep a standing pose of the library (``template``, one frame of a
   standing gesture clip); its upper arm and forearm get the smallest rotation (swing, no twist)
   that turns their rest direction onto the source's. Seated vs standing, bone lengths and bind
   poses then do not matter; the forearm twist of the source is lost.
3. **Rest at both ends**: over the last ``pad_s`` the arms are eased (smootherstep slerp) back to
   the clip's first pose, so every clip starts and ends at its rest pose B_G as a recorded standing
   gesture does (the motion between is untouched).
4. **Phases** with the walk-the-talk detector (``gestures.make_gesture``) on the retargeted clip,
   with ``hand_min_cm`` in place of the library's 15 cm (the seated corpus's hands move a few cm);
   a movement the detector rejects is skipped and listed.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ..annotate.motion import joint_speeds, recording_thresholds
from ..annotate.params import AnnotateParams
from ..easing import smootherstep
from ..errors import WalkTalkError
from ..kinematics import forward_kinematics_np, global_transforms_np
from ..rig import find_role
from ..rotations import matrix_to_quat_np, quat_slerp_np, quat_to_matrix_np
from ..skeleton import Motion
from .body import Body
from .gestures import Gesture, make_gesture
from .params import WalkTalkParams


@dataclass(frozen=True)
class SegmentParams:
    """Movement runs in a synthesized character's hand speeds (ours)."""

    min_s: float = 0.3      # shorter runs above the idle threshold are dropped
    merge_s: float = 0.3    # runs closer than this are one movement
    max_s: float = 3.0      # longer runs are split at their slowest frame
    pad_s: float = 0.5      # cut out with the movement on both sides; the last pad_s eases back to rest
    hand_min_cm: float = 2.0  # a hand gestures when its wrist excursion exceeds this


def _find(skel, role: str, path: str) -> int:
    j = find_role(skel, role)
    if j is None:
        raise WalkTalkError(f"skeleton lacks the {role} joint (patterns in convsynth_jax.rig.RIG_JOINTS); joints are "
                            f"{list(skel.names)}", path)
    return j


def _unit(v):
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-9)


def torso_frame(pos: np.ndarray, hips: int, neck: int, left: int, right: int) -> np.ndarray:
    """(F, 3, 3) orthonormal frames, columns (lateral to the left, up, forward = lateral x up),
    from global joint positions (F, J, 3): up = hips->neck, lateral = right->left upper arm."""
    up = _unit(pos[:, neck] - pos[:, hips])
    lat = pos[:, left] - pos[:, right]
    lat = _unit(lat - np.sum(lat * up, -1, keepdims=True) * up)
    return np.stack([lat, up, np.cross(lat, up)], axis=-1)


def swing(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(F, 3, 3) smallest rotations taking directions a (F, 3) onto b (F, 3)."""
    a, b = _unit(a), _unit(b)
    axis = np.cross(a, b)
    s = np.linalg.norm(axis, axis=-1)
    angle = np.arctan2(s, np.sum(a * b, -1))
    fallback = np.cross(a, np.array([1.0, 0.0, 0.0]))     # a and b opposite: any axis normal to a
    fallback = np.where(np.linalg.norm(fallback, axis=-1, keepdims=True) < 1e-6,
                        np.cross(a, np.array([0.0, 1.0, 0.0])), fallback)
    axis = np.where((s < 1e-9)[:, None], fallback, axis)
    return Rotation.from_rotvec(_unit(axis) * angle[:, None]).as_matrix()


def _to_quat(m: np.ndarray) -> np.ndarray:
    return matrix_to_quat_np(m)


def retarget_arms(source: Motion, template: Motion, body: Body, source_path: str = "") -> Motion:
    """The arm motion of ``source`` (any rig the shared table knows) on ``template``'s rig: a
    motion with template's first frame everywhere except both upper arms and forearms, which follow
    the source's bone directions in the torso frame (module docstring, step 2)."""
    ss = source.skeleton
    src = {r: _find(ss, r, source_path) for r in ("hips", "neck", "left_shoulder", "right_shoulder",
                                                  "left_elbow", "right_elbow", "left_hand", "right_hand")}
    f = source.num_frames
    spos = forward_kinematics_np(source)
    t_src = torso_frame(spos, src["hips"], src["neck"], src["left_shoulder"], src["right_shoulder"])
    tm = template.slice(0, 1)
    tj = body.joints
    tpos = forward_kinematics_np(tm)
    t_tgt = torso_frame(tpos, tj["hips"], tj["neck"], tj["upperarm_l"], tj["upperarm_r"])[0]
    g0 = global_transforms_np(tm)[1][0]
    local0 = quat_to_matrix_np(tm.rotations[0])
    offs = template.skeleton.offsets
    rot = np.repeat(np.asarray(tm.rotations, dtype=np.float64), f, axis=0)
    for s, full in (("l", "left"), ("r", "right")):
        u, e, h = tj[f"upperarm_{s}"], tj[f"elbow_{s}"], tj[f"hand_{s}"]
        collar = template.skeleton.parents[u]
        # source bone directions, torso frame -> target global
        d_u = spos[:, src[f"{full}_elbow"]] - spos[:, src[f"{full}_shoulder"]]
        d_f = spos[:, src[f"{full}_hand"]] - spos[:, src[f"{full}_elbow"]]
        d_u = np.einsum("ab,fcb,fc->fa", t_tgt, t_src, d_u)
        d_f = np.einsum("ab,fcb,fc->fa", t_tgt, t_src, d_f)
        g_c = g0[collar]
        g_u0 = np.broadcast_to(g0[u], (f, 3, 3))
        g_u = swing(g_u0 @ offs[e], d_u) @ g_u0
        g_e0 = g_u @ local0[e]
        g_e = swing(g_e0 @ offs[h], d_f) @ g_e0
        rot[:, u] = _to_quat(g_c.T @ g_u)
        rot[:, e] = _to_quat(np.swapaxes(g_u, -1, -2) @ g_e)
    tr = np.repeat(np.asarray(tm.translations, dtype=np.float64), f, axis=0)
    return Motion(template.skeleton, rot, tr, source.fps, source.name)


def ease_to_rest(clip: Motion, frames: int, body: Body) -> Motion:
    """Slerp both arms over the last ``frames`` frames back to the clip's first pose (smootherstep
    weight), so the clip ends where it started."""
    n = clip.num_frames
    frames = min(frames, n - 1)
    if frames <= 0:
        return clip
    t = np.linspace(0.0, 1.0, frames + 1)[1:]
    w = smootherstep(t)
    rot = np.array(clip.rotations, dtype=np.float64)
    arms = list(body.arm_l) + list(body.arm_r)
    tail = rot[n - frames:, arms]
    rot[n - frames:, arms] = quat_slerp_np(tail, np.broadcast_to(rot[0, arms], tail.shape), np.broadcast_to(
        w[:, None], tail.shape[:-1]))
    return dataclasses.replace(clip, rotations=rot)


def movement_runs(motion: Motion, sp: SegmentParams, annotate: AnnotateParams | None = None) -> list[tuple[int, int]]:
    """(start, end) frame runs (end exclusive) where either hand moves faster than the recording's
    Eq. 1 idle threshold (``annotate.motion``), merged and filtered by ``sp``."""
    ap = annotate or AnnotateParams()
    speeds = joint_speeds(motion, ap)
    th = recording_thresholds(speeds, float(ap.alpha_s))
    active = (speeds["LH"] > th["LH"]) | (speeds["RH"] > th["RH"])
    idx = np.flatnonzero(np.diff(np.r_[0, active.astype(int), 0]))
    runs = [(int(a), int(b)) for a, b in zip(idx[::2], idx[1::2])]
    fps, merged = motion.fps, []
    for a, b in runs:
        if merged and a - merged[-1][1] < sp.merge_s * fps:
            merged[-1] = (merged[-1][0], b)
        else:
            merged.append((a, b))
    out = []
    todo = [r for r in merged if r[1] - r[0] >= sp.min_s * fps]
    v = np.maximum(speeds["LH"], speeds["RH"])
    while todo:
        a, b = todo.pop(0)
        lo, hi = a + round(sp.min_s * fps), b - round(sp.min_s * fps)
        if b - a <= sp.max_s * fps or hi <= lo:
            out.append((a, b))
            continue
        cut = lo + int(np.argmin(v[lo:hi]))
        todo[:0] = [(a, cut), (cut, b)]
    return out


def synthesized_gestures(path: str | Path, template: Motion, body: Body, p: WalkTalkParams,
                         sp: SegmentParams = SegmentParams(), annotate: AnnotateParams | None = None):
    """Standing gesture clips on ``template``'s rig cut from a synthesized character's BVH.
    Returns (gestures: list[Gesture] in time order, each named ``<file stem>@<start>ms``; starts:
    list[float], each clip's first frame in the synthesized motion (s); skipped: list[str] of
    reasons)."""
    from ..io.bvh import load_bvh

    path = Path(path)
    m = load_bvh(path, fps=p.fps)
    pad = round(sp.pad_s * m.fps)
    phases = dataclasses.replace(p.phases, hand_min_cm=sp.hand_min_cm)
    out, starts, skipped = [], [], []
    for a, b in movement_runs(m, sp, annotate):
        lo, hi = max(0, a - pad), min(m.num_frames, b + pad)
        clip = retarget_arms(m.slice(lo, hi), template, body, str(path))
        clip = dataclasses.replace(clip, name=f"{path.stem}@{round(1000 * lo / m.fps)}ms")
        clip = ease_to_rest(clip, pad, body)
        try:
            g = make_gesture(clip, p.gait, phases, body)
        except WalkTalkError as e:
            skipped.append(f"{clip.name}: {e.reason}")
            continue
        out.append(Gesture(g.motion, g.phases, g.handedness, g.kind, clip.name))
        starts.append(lo / m.fps)
    return out, starts, skipped
