"""Two (or more) characters walking or jogging side by side while talking (paper Sec. 5-6).

Each character gets a locomotion loop (different clips, turned to walk along +Z, spaced
``spacing_cm`` apart), tiled to the timeline. Each utterance stress peak of that character's speech
gets a gesture from the library (seeded random choice) placed by the synchronization rule
(Sec. 4.2) and spliced with stylization (Sec. 4.1, 4.3), unless it would overlap the previous
gesture or leave the timeline (then the peak gets no gesture). Gaze (Sec. 5) is layered last.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import WalkTalkError
from ..rig import find_role
from ..rotations import quat_multiply_np, yaw_to_quat_np
from ..skeleton import Motion
from .gaze import (
    AAREvent,
    apply_gaze,
    events_from_gestures,
    statistics_events,
    validate_events,
)
from .locomotion import tile_contact, tile_loop
from .params import WalkTalkParams
from .pipeline import METHODS, LoopContext, splice_gesture
from .splice import JointLimits


@dataclass(frozen=True)
class Speaker:
    name: str
    peaks_s: tuple[float, ...]       # utterance stress peaks on the shared timeline (s)
    source: str = ""                 # where they came from (WAV / TSV)
    # (ours) the gesture (index into the character's pool) for each peak, in the order of peaks_s;
    # empty = a seeded random draw per peak (the clip library). Gestures cut from a synthesized
    # conversation keep their own times this way (see walktalk_demo's gesture_source).
    gesture_at: tuple[int, ...] = ()


@dataclass(frozen=True)
class DemoParams:
    duration_s: float = 60.0
    spacing_cm: float = 100.0        # lateral distance between neighbours (ours)
    min_gap_s: float = 0.2           # gap between one gesture's end and the next one's start (ours)
    aar: str = "inferred"            # inferred | random | scripted | statistics
    method: str = "stylized+synced"
    include_multi_peak: bool = True  # also use multi-peak gestures (never realigned)


def place_character(m: Motion, advance: np.ndarray, lateral_cm: float) -> Motion:
    """Turn the whole character about the origin so its loop advances along +Z, then shift it by
    ``lateral_cm`` along X, through the static top joint (joint_Root in bandai2): the locomotion
    itself is unchanged."""
    ang = -np.arctan2(advance[0], advance[2])  # rotate the advance onto +Z
    rot = np.array(m.rotations, dtype=np.float64)
    tr = np.array(m.translations, dtype=np.float64)
    if np.ptp(tr[:, 0], axis=0).max() > 1e-6 or np.abs(rot[:, 0] - rot[0, 0]).max() > 1e-9:
        raise WalkTalkError("the top joint must be static to place a character", m.name, "frame 0")
    q = yaw_to_quat_np(ang)
    rot[:, 0] = quat_multiply_np(np.broadcast_to(q, rot[:, 0].shape), rot[:, 0])
    tr[:, 0] = tr[:, 0] + np.array([lateral_cm, 0.0, 0.0])
    return dataclasses.replace(m, rotations=rot, translations=tr)


def run_demo(loops: list[LoopContext], gestures, speakers: list[Speaker], p: WalkTalkParams,
             dp: DemoParams, rng: np.random.Generator, scripted: list[AAREvent] | None = None,
             limits: JointLimits | None = None):
    """Returns (motions: name -> Motion, events: list of dict rows, aar: list[AAREvent]).
    ``gestures``: one list of :class:`GestureContext` shared by every character (the clip library),
    or a dict character name -> its own list (gestures cut from a synthesized conversation, see
    :mod:`.synthesized`). ``limits``: the library's range of motion for the stylization
    (``splice.respect_joint_limits``)."""
    fps = p.fps
    T = round(dp.duration_s * fps)
    if len(loops) < len(speakers):
        raise WalkTalkError(f"{len(speakers)} characters need as many loops, got {len(loops)}")
    names = [s.name for s in speakers]
    if len(set(names)) != len(names):
        raise WalkTalkError(f"character names must be unique: {names}")
    method = METHODS[dp.method]
    per_speaker = gestures if isinstance(gestures, dict) else {n: gestures for n in names}
    missing = [n for n in names if n not in per_speaker]
    if missing:
        raise WalkTalkError(f"no gesture source for characters {missing}", where="task.synthesized")
    pools = {n: [g for g in per_speaker[n] if dp.include_multi_peak or g.gesture.single_peak] for n in names}
    if not any(pools.values()):
        raise WalkTalkError("no gestures to use")
    for sp in speakers:
        if sp.gesture_at and (len(sp.gesture_at) != len(sp.peaks_s) or
                              not all(0 <= k < len(per_speaker[sp.name]) for k in sp.gesture_at)):
            raise WalkTalkError(f"character {sp.name}: gesture_at must give one gesture of its "
                                f"{len(per_speaker[sp.name])} per peak ({len(sp.peaks_s)})", sp.source or None)
    motions, rows, meta = {}, [], []
    for i, (sp, lc) in enumerate(zip(speakers, loops)):
        pool = pools[sp.name]
        for u in sp.peaks_s:
            if not 0 <= u <= dp.duration_s:
                raise WalkTalkError(f"utterance peak at {u:.3f} s outside the timeline 0-{dp.duration_s} s",
                                    sp.source or None, f"frame {round(u * fps)}")
        loco = tile_loop(lc.loop, T)
        contact = tile_contact(lc.loop, T)
        contact_alt = tile_contact(lc.loop, T, second=True)
        cur = loco
        busy_until = -1
        order = sorted(range(len(sp.peaks_s)), key=lambda k: sp.peaks_s[k])
        for k in order:
            u = sp.peaks_s[k]
            if sp.gesture_at:
                gc = per_speaker[sp.name][sp.gesture_at[k]]
            elif pool:
                gc = pool[int(rng.integers(len(pool)))]
            else:
                continue
            g = gc.gesture
            n0 = int(np.floor((u - p.splice.lead_s) * fps + 1e-9))
            earliest = n0 - int(np.floor(p.splice.max_shift_s * fps + 1e-9)) - g.phases.peaks[0] + g.phases.pb
            start_ok = earliest > busy_until + dp.min_gap_s * fps
            fits = n0 - int(p.splice.max_shift_s * fps) - g.phases.peaks[0] >= 0 and \
                n0 - g.phases.peaks[0] + g.motion.num_frames <= T
            if not (start_ok and fits) or n0 < 0:
                continue
            r = splice_gesture(lc, gc, u, T, p.splice, method, loco=cur, contact=contact, limits=limits)
            cur = r.motion
            busy_until = r.phases.re
            rows.append({"character": sp.name, "gesture": Path(g.name).stem, "gait": lc.loop.gait,
                         "t_prep_begin": r.phases.pb / fps, "t_stroke_peak": r.peak / fps,
                         "t_retraction_end": r.phases.re / fps, "utterance_peak_s": u, "shift_s": r.shift_s,
                         "contact_at_peak": bool(contact[r.peak]), "single_peak": g.single_peak,
                         # the second reading of the phases, and both readings at the nominal
                         # (unsynchronized) peak
                         "contact_alt_at_peak": bool(contact_alt[r.peak]),
                         "contact_at_nominal": bool(contact[r.nominal_peak]),
                         "contact_alt_at_nominal": bool(contact_alt[r.nominal_peak])})
            meta.append({"character": sp.name, "t_prep_begin": r.phases.pb / fps, "t_stroke_begin": r.phases.sb / fps,
                         "t_retraction_begin": r.phases.rb / fps, "t_retraction_end": r.phases.re / fps})
        lateral = (i - (len(speakers) - 1) / 2) * dp.spacing_cm
        motions[sp.name] = dataclasses.replace(place_character(cur, lc.loop.advance, lateral), name=sp.name)
    from ..kinematics import forward_kinematics_np

    roots = {}
    for n, m in motions.items():
        hips = find_role(m.skeleton, "hips")
        roots[n] = forward_kinematics_np(m)[:, hips]
    if dp.aar == "scripted":
        aar = list(scripted or [])
    elif dp.aar == "statistics":
        aar = statistics_events(names, dp.duration_s, p.gaze, rng)
    elif dp.aar in ("inferred", "random"):
        aar = events_from_gestures(meta, roots, dp.aar, rng, fps)
    else:
        raise WalkTalkError(f"unknown AAR mode {dp.aar!r}: inferred, random, scripted or statistics",
                            where="task.aar")
    validate_events(aar, names)
    out = {}
    for n, m in motions.items():
        others = {o: roots[o] for o in motions if o != n}
        out[n], _ = apply_gaze(m, n, aar, others, p.gaze, rng)
    return out, rows, aar
