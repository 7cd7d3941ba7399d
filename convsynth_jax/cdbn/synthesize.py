"""Synthesis (Sec. VI-B, VII-A): state posteriors from speech (and the constraint sequence) only,
motion = sum_i gamma_t(i) mu_i^motion, then key-point smoothing.

The paper's Eq. 3-4 are missing from the text; our reconstruction from the surrounding prose and
Eq. 6: gamma_t(i) = P(q_t = i | Speech_{1:T}, C_{1:T}, lambda) computed with the speech block of each
state's Gaussian (the motion node unobserved, i.e. marginalized), and E[Motion_t | Speech, C] =
sum_i gamma_t(i) mu_i^motion (Eq. 4 / Eq. 6). ``posterior`` selects gamma: ``smoother``
(forward-backward), ``filter`` (causal forward pass, Eq. 6's gamma_{c_{1:t}}), or ``viterbi`` (the
paper's wording "using the Viterbi algorithm": gamma is the one-hot best path, motion the means along
it). Smoothing (Busso et al. [5]): equidistant key points (15/s head, 12/s hands), converted to
quaternions and slerp-interpolated.
"""
from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ..errors import CDBNError
from .features import check_finite, head_euler_to_quat, head_joint_indices
from .hmm import batch_filter, batch_smoothed, batch_viterbi, pad_states
from .params import POSTERIORS, DBNModel


def _pad(n: int) -> int:
    return max(64, int(2 ** np.ceil(np.log2(max(n, 1)))))


def state_posteriors(model: DBNModel, speech: np.ndarray, constraints: np.ndarray | None = None,
                     posterior: str = "smoother") -> np.ndarray:
    """gamma (T, K) from normalized speech (T, d_s) and constraint codes (T,) (zeros if None)."""
    return state_posteriors_batch(model, [speech], None if constraints is None else [constraints], posterior)[0]


def _posteriors(model: DBNModel, x, cc, lengths, posterior: str) -> np.ndarray:
    """(B, L, K) posteriors of a padded batch; the model's states are padded to a multiple of 4 with
    inert states (:func:`.hmm.pad_states`: one compiled shape for nearby K) and sliced back."""
    K = model.num_states
    params = pad_states(model.means, model.covariances, model.initial, model.transitions)
    args = (jnp.asarray(x), jnp.asarray(cc), jnp.asarray(lengths)) + tuple(jnp.asarray(a, jnp.float32) for a in params)
    dims = tuple(model.speech_dims)
    if posterior == "smoother":
        g = np.asarray(batch_smoothed(*args, dims), np.float64)
    elif posterior == "filter":
        g = np.asarray(batch_filter(*args, dims)[1], np.float64)
    else:
        path = np.asarray(batch_viterbi(*args, dims)[0])
        g = np.eye(params[0].shape[0])[path]
    return g[:, :, :K]


def sample_state_path(model: DBNModel, filtered: np.ndarray, constraints: np.ndarray, rng) -> np.ndarray:
    """A state path (T,) drawn from P(q_1:T | speech, C) by backward sampling from the filtered
    posteriors (T, K) (``state_posteriors(..., "filter")``) and the constraint codes (T,): the
    state at t is drawn given the state drawn at t + 1. Its frame marginals are the smoothed posteriors."""
    filtered = np.asarray(filtered, np.float64)
    T, K = filtered.shape
    A = np.asarray(model.transitions, np.float64)
    q = np.empty(T, int)
    q[-1] = rng.choice(K, p=filtered[-1] / filtered[-1].sum())
    for t in range(T - 2, -1, -1):
        p = filtered[t] * A[constraints[t + 1], :, q[t + 1]]
        q[t] = rng.choice(K, p=p / p.sum())
    return q


def sample_motion(model: DBNModel, speech: np.ndarray, constraints: np.ndarray, rng) -> tuple[np.ndarray, np.ndarray]:
    """(means, draw), each (T, motion dims) in the model's normalized motion space: a state path drawn
    by :func:`sample_state_path` from the filtered posteriors of ``speech`` (T, d_s) under
    ``constraints`` (T,), its states' motion means, and one draw from each frame's state Gaussian."""
    q = sample_state_path(model, state_posteriors(model, speech, constraints, "filter"), constraints, rng)
    md = list(model.motion_dims)
    mu = np.asarray(model.means)[q][:, md]
    chol = np.linalg.cholesky(np.asarray(model.covariances)[:, md][:, :, md])[q]
    return mu, mu + np.einsum("tij,tj->ti", chol, rng.standard_normal((len(q), len(md))))


def state_posteriors_batch(model: DBNModel, speeches: list, constraints: list | None = None,
                           posterior: str = "smoother") -> list[np.ndarray]:
    """:func:`state_posteriors` of several turns in one call (one padded batch: one dispatch and one
    compiled shape per model instead of one per turn); returns the (T_i, K) posteriors."""
    if posterior not in POSTERIORS:
        raise CDBNError(f"unknown posterior {posterior!r}; expected one of {POSTERIORS}")
    n = len(speeches)
    if n == 0:
        return []
    cons = []
    for i, sp in enumerate(speeches):
        check_finite(sp, "speech", f"speech features of turn {i}")
        T = len(sp)
        c = np.zeros(T, np.int32) if constraints is None else np.asarray(constraints[i], np.int32)
        if len(c) != T:
            raise CDBNError(f"turn {i}: {T} speech frames but {len(c)} constraint codes")
        if c.size and (c.min() < 0 or c.max() >= model.num_constraints):
            raise CDBNError(f"constraint codes must lie in 0..{model.num_constraints - 1} {list(model.constraint_names)}")
        cons.append(c)
    L = _pad(max(len(sp) for sp in speeches))
    B = int(2 ** np.ceil(np.log2(n))) if n <= 16 else int(np.ceil(n / 16) * 16)
    D = model.means.shape[1]
    x = np.zeros((B, L, D), np.float32)
    cc = np.zeros((B, L), np.int32)
    lengths = np.zeros(B, np.int32)
    for i, (sp, c) in enumerate(zip(speeches, cons)):
        T = len(sp)
        x[i, :T][:, list(model.speech_dims)] = np.asarray(sp, np.float32)
        cc[i, :T] = c
        if T:
            cc[i, T:] = c[-1]
        lengths[i] = T
    g = _posteriors(model, x, cc, lengths, posterior)
    return [g[i, :len(sp)] for i, sp in enumerate(speeches)]


def expected_motion(model: DBNModel, gamma: np.ndarray) -> np.ndarray:
    """Eq. 4 / 6: (T, d_m) = gamma (T, K) @ mu^motion (K, d_m)."""
    return gamma @ np.asarray(model.means)[:, list(model.motion_dims)]


def keypoint_smooth(angles: np.ndarray, fps: float, keypoints_per_second: float) -> np.ndarray:
    """Key-point smoothing of head Euler angles (T, 3) degrees (pitch, yaw, roll): equidistant key points
    every fps / rate frames (and the last frame), quaternion slerp between them -> (T, 4) (w, x, y, z)."""
    T = len(angles)
    q = head_euler_to_quat(np.asarray(angles, np.float64))
    if T < 3 or keypoints_per_second <= 0:
        return q
    from scipy.spatial.transform import Rotation, Slerp

    step = max(fps / keypoints_per_second, 1.0)
    keys = np.unique(np.concatenate([np.round(np.arange(0, T - 1, step)).astype(int), [T - 1]]))
    # SciPy's Slerp (NumPy, any length without recompiling) between the key-point rotations
    slerp = Slerp(keys.astype(np.float64), Rotation.from_quat(q[keys][:, [1, 2, 3, 0]]))
    return slerp(np.arange(T, dtype=np.float64)).as_quat()[:, [3, 0, 1, 2]]


def synthesize_head(model: DBNModel, speech_z: np.ndarray, constraints: np.ndarray | None, posterior: str,
                    motion_mean: np.ndarray, motion_sd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(angles (T, 3) degrees, unsmoothed; gamma (T, K)) for z-normalized speech."""
    g = state_posteriors(model, speech_z, constraints, posterior)
    return expected_motion(model, g) * motion_sd + motion_mean, g


def head_into_motion(template, composite: np.ndarray, head_joints: tuple = ("neck", "head"), name: str = ""):
    """A full-skeleton Motion of len(composite) frames: every joint keeps the template's mean pose
    (first frame's translations, per-joint mean rotation), and the composed head rotation
    ``composite`` (F, 4) (w, x, y, z) is put on the last of ``head_joints`` after the fixed rotations of
    the others (so the composition Neck * Head equals ``composite``)."""
    from scipy.spatial.transform import Rotation

    from ..skeleton import Motion

    skel = template.skeleton
    F = len(composite)
    rot = np.asarray(template.rotations, np.float64)
    mean_rot = np.zeros((skel.num_joints, 4))
    for j in range(skel.num_joints):
        mean_rot[j] = Rotation.from_quat(rot[:, j][:, [1, 2, 3, 0]]).mean().as_quat()[[3, 0, 1, 2]]
    rots = np.broadcast_to(mean_rot, (F, skel.num_joints, 4)).copy()
    idx = head_joint_indices(skel, head_joints, name or template.name)
    pre = Rotation.identity()
    for j in idx[:-1]:
        pre = pre * Rotation.from_quat(mean_rot[j][[1, 2, 3, 0]])
    head = pre.inv() * Rotation.from_quat(np.asarray(composite)[:, [1, 2, 3, 0]])
    rots[:, idx[-1]] = head.as_quat()[:, [3, 0, 1, 2]]
    trans = np.broadcast_to(np.asarray(template.translations[0]), (F,) + template.translations.shape[1:]).copy()
    return Motion(skel, rots, trans, float(template.fps), name or template.name)


def head_onto_body(body, composite: np.ndarray, head_joints: tuple = ("neck", "head"), name: str = ""):
    """``body`` (a Motion of len(composite) frames, e.g. a training recording) with its head replaced:
    every joint but the last of ``head_joints`` keeps the recording's rotation per frame, and the last
    one is set so that the composition of ``head_joints`` equals ``composite`` (F, 4) (w, x, y, z) at
    every frame (the head rotation relative to the neck's parent, as :func:`head_into_motion`)."""
    import dataclasses

    from scipy.spatial.transform import Rotation

    F = len(composite)
    if body.num_frames != F:
        raise CDBNError(f"head_onto_body: the body has {body.num_frames} frames but the head {F}")
    rots = np.array(body.rotations, np.float64)
    idx = head_joint_indices(body.skeleton, head_joints, name or body.name)
    pre = Rotation.identity(F)
    for j in idx[:-1]:
        pre = pre * Rotation.from_quat(rots[:, j][:, [1, 2, 3, 0]])
    head = pre.inv() * Rotation.from_quat(np.asarray(composite, np.float64)[:, [1, 2, 3, 0]])
    rots[:, idx[-1]] = head.as_quat()[:, [3, 0, 1, 2]]
    return dataclasses.replace(body, rotations=rots, translations=np.array(body.translations), name=name or body.name)


def body_excerpt(motions: list, num_frames: int, rng: np.random.Generator):
    """``num_frames`` frames of one of ``motions`` (drawn with ``rng``) from a random start; a clip
    shorter than the window is played forward and back (no jump). ``motions``: a non-empty list."""
    if not motions:
        raise CDBNError("body_excerpt: no recordings to take the body from")
    m = motions[int(rng.integers(len(motions)))]
    F = m.num_frames
    if F >= num_frames:
        s = int(rng.integers(0, F - num_frames + 1))
        return m.slice(s, s + num_frames)
    period = max(2 * F - 2, 1)
    t = np.arange(num_frames) % period
    idx = np.where(t < F, t, period - t) if F > 1 else np.zeros(num_frames, int)
    import dataclasses

    return dataclasses.replace(m, rotations=np.asarray(m.rotations)[idx], translations=np.asarray(m.translations)[idx])
