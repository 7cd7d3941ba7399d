"""One splice end to end (paper Fig. 4): stylize -> synchronize -> splice, for the three methods
compared in the evaluation: ``naive`` (raw gesture DOFs spliced with Eq. 2 at the nominal time),
``stylized`` (+ Sec. 4.1), ``stylized+synced`` (+ Sec. 4.2 alignment and elbow bounce).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from ..skeleton import Motion
from .body import Body, find_body, mask
from .gestures import Gesture, Phases
from .locomotion import Loop, tile_contact, tile_loop
from .params import SpliceParams
from .splice import (
    JointLimits,
    LoopStats,
    arm_joints,
    bounce_offsets,
    bounce_reserve,
    check_placement,
    elbow_dof,
    joint_euler,
    loop_stats,
    place_gesture_arms,
    rest_pose,
    splice_arrays,
    splice_weights,
    stylize,
    stylize_bands,
)
from .sync import align_peak, nominal_frame, shift_frames


@dataclass(frozen=True)
class Method:
    stylize: bool
    sync: bool
    bounce: bool


# The evaluation's methods, looked up by name (config lists the names).
METHODS: dict[str, Method] = {
    "naive": Method(stylize=False, sync=False, bounce=False),
    "stylized": Method(stylize=True, sync=False, bounce=False),
    "stylized+synced": Method(stylize=True, sync=True, bounce=True),
}


@dataclass(frozen=True)
class LoopContext:
    """A loop with its arm statistics: euler (N, A, 3) over both arms' joints (``joints``)."""

    loop: Loop
    body: Body
    joints: tuple[int, ...]
    euler: np.ndarray
    stats: LoopStats
    elbow_dof: dict
    # (A, 3) per-DOF smallest std over the loaded loops of this loop's gait (``band_std=gait_min``,
    # ours; set by :func:`share_gait_band`); None = the loop's own
    gait_min_std: np.ndarray | None = None
    # side -> (mean, std) elbow bend in degrees over the loop, filled on first use by
    # walktalk.elbow.lc_bend (a cache held by the context it describes)
    elbow_bend: dict = field(default_factory=dict, init=False, repr=False, compare=False)


@dataclass(frozen=True)
class GestureContext:
    gesture: Gesture
    joints: tuple[int, ...]       # the gesturing arm(s)' joints
    euler: np.ndarray             # (Fg, A, 3)
    rest: np.ndarray              # B_G (A, 3)


def loop_context(loop: Loop, body: Body | None = None) -> LoopContext:
    body = body or find_body(loop.motion.skeleton, loop.source)
    joints = arm_joints(body)
    e = joint_euler(loop.motion, joints)
    dofs = {s: elbow_dof(e[:, joints.index(body.joints[f"elbow_{s}"])]) for s in ("l", "r")}
    return LoopContext(loop, body, joints, e, loop_stats(e), dofs)


def share_gait_band(loops: list) -> list:
    """The loops of one gait, each given the per-DOF minimum of their stds (``gait_min_std``), for
    ``band_std=gait_min`` (ours). Being a minimum, it never exceeds a loop's own std."""
    if not loops:
        return loops
    m = np.min([lc.stats.std for lc in loops], axis=0)
    return [dataclasses.replace(lc, gait_min_std=m) for lc in loops]


def band_stats(lc: LoopContext, p: SpliceParams, idx) -> LoopStats:
    """B_L and the std the c-sigma band is built from (``p.band_std``), rows ``idx``."""
    std = lc.stats.std
    if p.band_std == "gait_min" and lc.gait_min_std is not None:
        std = lc.gait_min_std
    return LoopStats(lc.stats.mean[idx], std[idx])


def pad_gesture(g: Gesture, frames: int) -> Gesture:
    """Hold the gesture's first and last pose for ``frames`` extra frames and widen t_Pb / t_Re
    by as much (ours): the Eq. 2 blend toward the gesture then starts while the gesture is still
    at rest instead of while its own preparation is already moving, which removes most of the
    wrist-jerk excess at t_Pb (experiments/bench/bench_walktalk.py reports the effect)."""
    if frames <= 0:
        return g
    m = g.motion
    rot = np.concatenate([np.repeat(m.rotations[:1], frames, 0), m.rotations, np.repeat(m.rotations[-1:], frames, 0)])
    tr = np.concatenate([np.repeat(m.translations[:1], frames, 0), m.translations,
                         np.repeat(m.translations[-1:], frames, 0)])
    ph = g.phases.shifted(frames)
    ph = dataclasses.replace(ph, pb=ph.pb - frames, re=ph.re + frames)
    return dataclasses.replace(g, motion=dataclasses.replace(m, rotations=rot, translations=tr), phases=ph)


def gesture_context(g: Gesture, body: Body, pad_frames: int = 0) -> GestureContext:
    g = pad_gesture(g, pad_frames)
    joints = arm_joints(body, g.sides)
    e = joint_euler(g.motion, joints)
    return GestureContext(g, joints, e, rest_pose(e, g.phases))


@dataclass(frozen=True)
class SpliceResult:
    motion: Motion
    phases: Phases            # on the timeline
    offset: int               # timeline frame of the gesture's first frame
    nominal_peak: int         # timeline frame before synchronization
    peak: int                 # timeline frame of the (first) stroke peak
    shift_s: float
    contact: np.ndarray       # (T,) timeline contact labels
    arm_euler: np.ndarray     # (Fg, A, 3) gesture arm DOFs as spliced (after stylization and bounce)
    styled_euler: np.ndarray  # (Fg, A, 3) after stylization, before the bounce


def splice_gesture(lc: LoopContext, gc: GestureContext, utterance_peak_s: float, num_frames: int,
                   p: SpliceParams, method: Method | str, loco: Motion | None = None,
                   contact: np.ndarray | None = None, limits: JointLimits | None = None) -> SpliceResult:
    """Splice one gesture into ``num_frames`` frames of the tiled loop so its stroke peak serves
    the stress peak at ``utterance_peak_s`` (seconds on the timeline). ``limits``: the library's
    range of motion, used by the stylization when ``p.respect_joint_limits``."""
    m = METHODS[method] if isinstance(method, str) else method
    g = gc.gesture
    fps = lc.loop.motion.fps
    loco = tile_loop(lc.loop, num_frames) if loco is None else loco
    contact = tile_contact(lc.loop, num_frames) if contact is None else contact
    n0 = nominal_frame(utterance_peak_s, p.lead_s, fps, num_frames, g.name)
    shift = align_peak(n0, contact, shift_frames(p.max_shift_s, fps), not g.single_peak) if m.sync else 0
    peak = n0 + shift
    offset = peak - g.phases.peaks[0]
    idx = [lc.joints.index(j) for j in gc.joints]
    e = gc.euler
    st, lim, reserve, bounce_gain = None, None, None, 1.0
    bounce = m.bounce and p.k_bounce != 0.0
    if bounce:
        check_placement(offset, g.motion.num_frames, num_frames, g.name)
    stylized = m.stylize and (g.kind != "deictic" or p.stylize_deictic)
    if stylized:
        st = band_stats(lc, p, idx)
        lim = limits if p.respect_joint_limits else None
        bands = dict(mode=p.joint_limit_mode, softness_deg=p.joint_limit_softness_deg)
        coupling = p.rescale_coupling
        if bounce and p.bounce_fit == "reserve":
            # (ours) keep room in the elbow's band for the bounce on both sides, so adding it
            # afterwards stays inside the band without rescaling the gesture a second time; the
            # bounce takes at most half of either side of the band (else it is scaled down, bounce_gain)
            lo, hi = bounce_reserve(lc.loop.root_height, p.k_bounce)
            down, up = stylize_bands(st, p.c, lim, gc.joints, **bands)
            reserve = (np.zeros_like(st.mean), np.zeros_like(st.mean))
            for s in g.sides:
                a = gc.joints.index(lc.body.joints[f"elbow_{s}"])
                d = lc.elbow_dof[s]
                bounce_gain = min(bounce_gain, 0.5 * down[a, d] / lo if lo > 0 else 1.0,
                                  0.5 * up[a, d] / hi if hi > 0 else 1.0)
            for s in g.sides:
                a = gc.joints.index(lc.body.joints[f"elbow_{s}"])
                reserve[0][a, lc.elbow_dof[s]], reserve[1][a, lc.elbow_dof[s]] = bounce_gain * lo, bounce_gain * hi
        e = stylize(e, st, gc.rest, p.c, lim, gc.joints, reserve, **bands, coupling=coupling)
    styled = e
    if bounce:
        d_b = bounce_gain * bounce_offsets(lc.loop.root_height, p.k_bounce, offset, g.motion.num_frames)
        e = e.copy()
        for s in g.sides:
            a = gc.joints.index(lc.body.joints[f"elbow_{s}"])
            e[:, a, lc.elbow_dof[s]] += d_b   # R' = R + k dH_root (Sec. 4.2)
        if lim is not None and p.bounce_fit == "rescale":
            # (ours) the bounce must not push an elbow the stylization brought to its limit past
            # it: the bounced deviation is rescaled once more into the same bands (B_D = 0 now)
            e = stylize(e, st, st.mean, p.c, lim, gc.joints, **bands, coupling=coupling)
    gest_q = place_gesture_arms(loco, g, e, gc.joints, offset)
    ph = g.phases.shifted(offset)
    w = splice_weights(num_frames, ph, p.ease)
    rot = splice_arrays(np.asarray(loco.rotations), gest_q, w, mask(loco.skeleton.num_joints, gc.joints))
    out = Motion(loco.skeleton, rot, loco.translations, fps, f"{g.name}+{lc.loop.source}")
    return SpliceResult(out, ph, offset, n0, peak, shift / fps, contact, e, styled)
