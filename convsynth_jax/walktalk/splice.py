"""Stylized splicing (paper Sec. 4.1, 4.2 "Synthesis", 4.3 Eq. 1-2).

Arm DOFs are the BVH Euler channels (degrees in the paper, radians here) of every joint of both
arms (shoulder, upper arm, forearm, hand), unwrapped over time.

* Stylization (Sec. 4.1): B_L = mean arm pose of the loop, B_G = rest pose of the gesture (mean of
  its frames outside t_Pb..t_Re), M'_G = M_G + (B_L - B_G). Each DOF's deviation from B_L is then
  rescaled linearly (not clipped) so that its largest excursion over the clip is at most c * STD_L;
  optionally (ours, on by default) also no farther than the library's range of motion
  (:class:`JointLimits`, :func:`stylize_bands`). Deictic gestures are left alone.
* Elbow bounce (Sec. 4.2): R'_elbow = R_elbow + k * dH_root, dH_root = loop root height minus its
  mean (cm), on the forearm DOF that varies most in the loop, over the whole gesture.
* Splicing (Sec. 4.3): lower body and torso from the locomotion (Eq. 1); arms from the loop
  outside t_Pb..t_Re, from the gesture inside the stroke and holds, slerp in preparation and
  retraction (Eq. 2). Only the gesturing arm(s) are spliced; the other keeps the loop's swing (ours).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
from scipy.spatial.transform import Rotation

from ..easing import EASES
from ..errors import WalkTalkError
from ..rotations import quat_slerp
from ..skeleton import Motion
from .body import Body
from .gestures import Gesture, Phases


def arm_joints(body: Body, sides=("l", "r")) -> tuple[int, ...]:
    return tuple(j for s in sides for j in body.arm(s))


def joint_euler(motion: Motion, joints) -> np.ndarray:
    """(F, len(joints), 3) Euler angles (radians, BVH channel order of each joint), unwrapped in time.

    Float64 statistics outside jit use SciPy (intrinsic upper-case orders, the BVH convention, the
    same as ``rotations.quat_to_euler``; a test checks the two agree)."""
    out = np.empty((motion.num_frames, len(joints), 3))
    for a, j in enumerate(joints):
        q = np.asarray(motion.rotations[:, j], dtype=np.float64)
        out[:, a] = Rotation.from_quat(q[:, [1, 2, 3, 0]]).as_euler(motion.skeleton.rotation_order(j))
    return np.unwrap(out, axis=0)


def euler_to_joint_quats(euler: np.ndarray, motion: Motion, joints) -> np.ndarray:
    """Inverse of :func:`joint_euler`: (F, A, 3) -> (F, A, 4) (w, x, y, z)."""
    out = np.empty(euler.shape[:2] + (4,))
    for a, j in enumerate(joints):
        xyzw = Rotation.from_euler(motion.skeleton.rotation_order(j), euler[:, a]).as_quat()
        out[:, a] = xyzw[:, [3, 0, 1, 2]]
    return out


@dataclass(frozen=True)
class LoopStats:
    """Arm-DOF statistics of a locomotion loop: mean B_L and std (A, 3), radians."""

    mean: np.ndarray
    std: np.ndarray


def loop_stats(loop_euler: np.ndarray) -> LoopStats:
    return LoopStats(loop_euler.mean(axis=0), loop_euler.std(axis=0))


def rest_pose(gesture_euler: np.ndarray, ph: Phases) -> np.ndarray:
    """B_G: mean of the frames outside t_Pb..t_Re (the first frame if there are none). (A, 3)."""
    n = gesture_euler.shape[0]
    keep = np.r_[0:ph.pb, ph.re + 1:n]
    return gesture_euler[keep].mean(axis=0) if keep.size else gesture_euler[0]


def wrap_angle(x):
    """Angles (radians) wrapped into [-pi, pi)."""
    return (np.asarray(x) + np.pi) % (2 * np.pi) - np.pi


@dataclass(frozen=True)
class JointLimits:
    """Range of motion of the arm DOFs seen in a clip library: per DOF (A, 3), the limits are
    ``ref + lo`` .. ``ref + hi`` with ``ref`` the DOF's circular mean over all frames and ``lo``,
    ``hi`` percentiles of the wrapped offsets from it (so no limit straddles the +-pi seam).
    ``joints`` are the skeleton indices the A rows belong to."""

    joints: tuple
    ref: np.ndarray
    lo: np.ndarray
    hi: np.ndarray

    def rows(self, joints) -> list[int]:
        return [self.joints.index(j) for j in joints]

    def violations(self, euler: np.ndarray, joints) -> np.ndarray:
        """euler (F, len(joints), 3) -> (F, len(joints), 3) bool: DOF outside its limits."""
        idx = self.rows(joints)
        d = wrap_angle(euler - self.ref[idx])
        return (d < self.lo[idx]) | (d > self.hi[idx])


def joint_limits(eulers, joints, percentiles=(0.5, 99.5), tolerance_deg: float = 0.0) -> JointLimits:
    """:class:`JointLimits` from a list of per-clip arm DOFs (F_i, A, 3) (every frame pooled),
    widened by ``tolerance_deg`` on both sides."""
    x = np.concatenate(list(eulers))
    ref = np.angle(np.exp(1j * x).mean(axis=0))
    d = wrap_angle(x - ref)
    tol = np.radians(tolerance_deg)
    return JointLimits(tuple(joints), ref, np.percentile(d, percentiles[0], axis=0) - tol,
                       np.percentile(d, percentiles[1], axis=0) + tol)


def soft_cap(band, room, width):
    """Smooth version of ``min(band, room)`` (ours, ``joint_limit_mode=soft``): ``room - width *
    softplus((room - band) / width)``, floored at 0. It is <= min(band, room) everywhere, equals
    ``band`` up to ``width * log(1 + exp(-(room - band) / width))`` far inside the limit, tends to
    ``room`` (never reaching it) as the band grows past it, and grows strictly with ``band``: a loop
    whose band would cross the limit still moves the stroke, where the hard cut pins it at the limit."""
    band, room = np.asarray(band, dtype=np.float64), np.asarray(room, dtype=np.float64)
    x = (room - band) / width
    softplus = np.logaddexp(0.0, x)
    return np.maximum(room - width * softplus, 0.0)


def stylize_bands(stats: LoopStats, c: float, limits: JointLimits | None = None, joints=None,
                  mode: str = "hard", softness_deg: float = 10.0):
    """Allowed deviation below and above B_L per DOF, (A, 3) each, >= 0.

    The paper's band is +- c std of the loop (Sec. 4.1). With ``limits`` (ours) each side is also
    cut where it would leave the range of motion of the clip library: with c = 3 the band of a jog
    loop, whose elbows are already flexed ~90 deg, reaches ~140 deg of flexion (no clip goes past
    ~120), so a raise-hand gesture was spliced with the elbow folded beyond its limit. ``mode``:
    "hard" cuts each side at the limit (min), "soft" (ours) saturates it smoothly toward the limit
    (:func:`soft_cap`, width ``softness_deg``)."""
    down = up = c * np.asarray(stats.std, dtype=np.float64)
    if limits is not None:
        idx = limits.rows(joints)
        off = wrap_angle(np.asarray(stats.mean) - limits.ref[idx])   # B_L inside the limit frame
        room_dn, room_up = np.maximum(off - limits.lo[idx], 0.0), np.maximum(limits.hi[idx] - off, 0.0)
        if mode == "soft":
            w = np.radians(softness_deg)
            down, up = soft_cap(down, room_dn, w), soft_cap(up, room_up, w)
        elif mode == "hard":
            down, up = np.minimum(down, room_dn), np.minimum(up, room_up)
        else:
            raise WalkTalkError(f"unknown joint-limit mode {mode!r}", where="walktalk.splice.joint_limit_mode")
    return down, up


def stylize(gesture_euler, stats: LoopStats, b_g, c: float, limits: JointLimits | None = None,
            joints=None, reserve=None, mode: str = "hard", softness_deg: float = 10.0,
            coupling: float = 0.0) -> np.ndarray:
    """:func:`stylize_kernel` padded to a bucket length (edge frames repeat, so maxima do not change);
    ``limits`` (with the ``joints`` of the A rows) narrows the band, see :func:`stylize_bands`.
    ``reserve`` (ours): a pair (below, above) of (A, 3) arrays >= 0 taken off the band's two sides,
    room kept free for a disturbance added afterwards (the elbow bounce, see
    :func:`bounce_reserve`). ``mode``, ``softness_deg``: how the band meets ``limits``.
    ``coupling`` (ours, ``splice.rescale_coupling``): 0 = the paper's one factor per DOF, 1 = one
    factor per joint (its three DOFs' smallest), in between a geometric blend of the two (see
    :func:`stylize_kernel`)."""
    if not 0.0 <= coupling <= 1.0:
        raise WalkTalkError(f"rescale coupling must be in [0, 1], got {coupling}", where="walktalk.splice.rescale_coupling")
    f = gesture_euler.shape[0]
    p = bucket(f)
    x = np.pad(gesture_euler, ((0, p - f), (0, 0), (0, 0)), mode="edge")
    down, up = stylize_bands(stats, c, limits, joints, mode, softness_deg)
    if reserve is not None:
        down = np.maximum(down - reserve[0], 0.0)
        up = np.maximum(up - reserve[1], 0.0)
    f32 = partial(np.asarray, dtype=np.float32)   # NumPy in, jit transfers (jnp.asarray dispatches a cast)
    return np.asarray(stylize_kernel(f32(x), f32(stats.mean), f32(down), f32(up), f32(b_g), np.float32(coupling)),
                      dtype=np.float64)[:f]


@jax.jit
def stylize_kernel(gesture_euler, b_l, down, up, b_g, coupling=0.0):
    """Sec. 4.1. gesture_euler: (F, A, 3); b_l, down, up, b_g: (A, 3) -> (F, A, 3).

    M'_G = M_G + (B_L - B_G); deviation D = M'_G - B_L; per DOF one factor
    s = min(1, down / max_t(-D), up / max_t D) (down = up = c std in the paper), result B_L + s D:
    a linear rescaling of the deviation (not clipping), so every DOF stays within B_L - down ..
    B_L + up.

    ``coupling`` = g (ours, ``splice.rescale_coupling``): each DOF's factor becomes
    s^(1-g) * s_min^g with s_min the smallest factor of the joint's three DOFs; it is <= s, so every
    DOF stays inside its band, and at g = 1 the joint's deviation is scaled uniformly. Why: the
    paper's per-DOF factors differ wildly within one joint (a raise-hand's upper arm 0.17 / 0.53 /
    0.99, its elbow flexion 0.29) and the wrist jerk of a fast movement, small in the recording
    because the joints' channels move in concert, is no longer cancelled: the stroke-to-retraction
    turn of a raise-hand spliced onto a walk reached 2.35x the source clips' largest wrist jerk
    (g = 0.25: 1.74x; README, "Jerk at the splices"). The price is a smaller gesture (a joint's
    channels shrink toward its most constrained one's factor).
    """
    dev = gesture_euler + (b_l - b_g) - b_l
    below = jnp.max(-dev, axis=0)
    above = jnp.max(dev, axis=0)
    s_lo = jnp.where(below > down, down / jnp.where(below > 0, below, 1.0), 1.0)
    s_hi = jnp.where(above > up, up / jnp.where(above > 0, above, 1.0), 1.0)
    s = jnp.minimum(s_lo, s_hi)
    s_min = jnp.min(s, axis=-1, keepdims=True)
    s = jnp.where(coupling > 0, s ** (1.0 - coupling) * s_min ** coupling, s)
    return b_l + dev * s


def splice_weights(num_frames: int, ph: Phases, ease: str = "linear") -> np.ndarray:
    """Eq. 2 blend weight toward the gesture per timeline frame, (T,).

    0 outside [t_Pb, t_Re]; (t - t_Pb) / (t_Pe - t_Pb + 1) in preparation; 1 from t_Sb through
    the holds to t_Se; (t_Re - t) / (t_Re - t_Rb + 1) in retraction. NOTE: Eq. 2 as printed uses
    slerp(M_L, M_G, (t - t_Rb) / (t_Re - t_Rb + 1)) in retraction, which would blend *toward* the
    gesture; the text says retraction returns the arm to the locomotion swing, so we use the
    mirrored weight, which ends at the loop pose on t_Re.

    ``ease="smootherstep"`` (ours, the configured default) maps each ramp weight w through
    6w^5 - 15w^4 + 10w^3, which has zero first and second derivatives at both ends, so the blend
    adds no velocity or acceleration kink at t_Pb, t_Sb, t_Rb, t_Re (the paper's linear ramp does).
    """
    if ease not in EASES:
        raise WalkTalkError(f"unknown ease {ease!r}; choose one of {sorted(EASES)}", where="walktalk.splice.ease")
    t = np.arange(num_frames, dtype=np.float64)
    w = np.zeros(num_frames)
    prep = (t >= ph.pb) & (t <= ph.pe)
    w[prep] = (t[prep] - ph.pb) / (ph.pe - ph.pb + 1)
    w[(t > ph.pe) & (t < ph.rb)] = 1.0
    ret = (t >= ph.rb) & (t <= ph.re)
    w[ret] = (ph.re - t[ret]) / (ph.re - ph.rb + 1)
    return EASES[ease](w)


def _splice_frame(loco_q, gest_q, w, arm_mask):
    """One frame of Eq. 1-2: loco_q, gest_q: (J, 4); w scalar; arm_mask (J,) bool -> (J, 4)."""
    blended = quat_slerp(loco_q, gest_q, jnp.broadcast_to(w, loco_q.shape[:-1]))
    return jnp.where(arm_mask[:, None] & (w > 0), blended, loco_q)


@partial(jax.jit, donate_argnums=())
def splice_kernel(loco_q, gest_q, w, arm_mask):
    """Eq. 1-2 over a timeline: loco_q, gest_q: (T, J, 4); w: (T,); arm_mask: (J,) -> (T, J, 4).
    Joints outside ``arm_mask`` (lower body, torso, the idle arm) are copied from the locomotion."""
    return jax.vmap(_splice_frame, in_axes=(0, 0, 0, None))(loco_q, gest_q, w, arm_mask)


def bucket(n: int, minimum: int = 64) -> int:
    """Pad lengths to powers of two so the jitted kernels compile a handful of times."""
    return max(minimum, 1 << (int(n) - 1).bit_length())


def splice_arrays(loco_q: np.ndarray, gest_q: np.ndarray, w: np.ndarray, arm_mask: np.ndarray) -> np.ndarray:
    """:func:`splice_kernel` over the frames where ``w > 0`` (padded to a bucket length); every other
    frame is the kernel's output there anyway, the locomotion in float32, and is copied. Shapes as
    the kernel; float32 out."""
    out = np.array(loco_q, dtype=np.float32)
    on = np.flatnonzero(np.asarray(w) > 0)
    if on.size == 0:
        return out
    lo, hi = int(on[0]), int(on[-1]) + 1
    n = hi - lo
    p = bucket(n)
    pad = ((0, p - n), (0, 0), (0, 0))
    f32 = partial(np.asarray, dtype=np.float32)
    res = splice_kernel(f32(np.pad(loco_q[lo:hi], pad, mode="edge")), f32(np.pad(gest_q[lo:hi], pad, mode="edge")),
                        f32(np.pad(np.asarray(w)[lo:hi], (0, p - n))), np.asarray(arm_mask, dtype=bool))
    out[lo:hi] = np.asarray(res)[:n]
    return out


def bounce_offsets(root_height: np.ndarray, k: float, offset: int, frames: int) -> np.ndarray:
    """Sec. 4.2 elbow bounce k * dH_root (radians) for ``frames`` gesture frames placed at timeline
    frame ``offset``: dH_root = the loop's root height minus its mean (cm), k in degrees per cm."""
    h = np.asarray(root_height, dtype=np.float64)
    d_h = (h - h.mean())[np.arange(offset, offset + frames) % len(h)]
    return np.radians(k * d_h)


def bounce_reserve(root_height: np.ndarray, k: float) -> tuple[float, float]:
    """Room (radians, below and above) the bounce k * dH_root can take anywhere on the loop: the
    loop's largest fall below and rise above its mean root height, times k (for ``bounce_fit=reserve``)."""
    h = np.asarray(root_height, dtype=np.float64)
    d = np.radians(k * (h - h.mean()))
    return float(max(-d.min(), 0.0)), float(max(d.max(), 0.0))


def elbow_dof(loop_euler_elbow: np.ndarray) -> int:
    """Index (0..2) of the forearm Euler channel with the largest std over the loop (the flexion)."""
    return int(np.argmax(loop_euler_elbow.std(axis=0)))


def check_placement(offset: int, gesture_frames: int, timeline_frames: int, name: str) -> None:
    if offset < 0 or offset + gesture_frames > timeline_frames:
        raise WalkTalkError(f"gesture placed at frames {offset}..{offset + gesture_frames - 1} falls outside the "
                            f"timeline of {timeline_frames} frames (utterance time too early or too late)",
                            name, f"frame {offset if offset < 0 else offset + gesture_frames - 1}")


def place_gesture_arms(loco: Motion, gesture: Gesture, arm_euler: np.ndarray, joints, offset: int) -> np.ndarray:
    """Timeline-length gesture rotations (T, J, 4): the loop's everywhere, the gesture's (possibly
    stylized) arm joints ``joints`` from ``arm_euler`` (Fg, A, 3) at frames offset..offset+Fg-1."""
    check_placement(offset, gesture.motion.num_frames, loco.num_frames, gesture.name)
    g = np.array(loco.rotations, dtype=np.float64)
    q = euler_to_joint_quats(arm_euler, gesture.motion, joints)
    g[offset:offset + q.shape[0], list(joints)] = q
    return g
