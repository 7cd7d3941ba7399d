"""Synchronization of stroke peaks with speech and footsteps (paper Sec. 4.2 "Alignment").

Rule: the stroke peak goes ``lead_s`` before the utterance's stress peak (ours: 0.2 s, the near
end of the 0.2-0.6 s window the paper cites, so the peak is never after the stress). If that frame
is not in a locomotion contact phase, search up to ``max_shift_s`` (0.6 s) earlier for the first
(nearest) contact frame and put the peak there: shift in [-max_shift_s, 0]. If none is found the
gesture stays at the nominal time. Gestures with several stroke peaks are never realigned.
"""
from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from ..errors import WalkTalkError


def nominal_frame(utterance_peak_s: float, lead_s: float, fps: float, num_frames: int, where: str = "") -> int:
    """Frame of the nominal stroke peak; a :class:`WalkTalkError` if outside the timeline."""
    f = int(np.floor((utterance_peak_s - lead_s) * fps + 1e-9))
    if not (0 <= f < num_frames) or not (0 <= utterance_peak_s <= num_frames / fps):
        raise WalkTalkError(f"utterance peak at {utterance_peak_s:.3f} s (nominal stroke peak at frame {f}) lies "
                            f"outside the timeline of {num_frames} frames ({num_frames / fps:.2f} s)", where or None,
                            f"frame {f}")
    return f


def align_peak(nominal: int, contact: np.ndarray, max_shift_frames: int, multi_peak: bool) -> int:
    """Shift in frames (<= 0) that moves a stroke peak at ``nominal`` into a contact phase."""
    if multi_peak or contact[nominal]:
        return 0
    for d in range(1, max_shift_frames + 1):
        t = nominal - d
        if t < 0:
            break
        if contact[t]:
            return -d
    return 0


@partial(jax.jit, static_argnames=("max_shift_frames",))
def align_kernel(nominal, contact, multi_peak, max_shift_frames: int):
    """Vectorized :func:`align_peak` for many gestures on one timeline.

    nominal: (G,) int frames; contact: (T,) bool; multi_peak: (G,) bool -> (G,) int shifts (<= 0).
    """
    def one(n, multi):
        d = jnp.arange(max_shift_frames + 1)
        t = n - d
        ok = (t >= 0) & contact[jnp.clip(t, 0, contact.shape[0] - 1)]
        first = jnp.argmax(ok)
        shift = jnp.where(jnp.any(ok), -first, 0)
        return jnp.where(multi, 0, shift)

    return jax.vmap(one)(nominal, multi_peak)


def shift_frames(max_shift_s: float, fps: float) -> int:
    return int(np.floor(max_shift_s * fps + 1e-9))
