"""One seed derivation for every task: (base seed, fold, condition, session, window, role) -> seed.

``task=loo`` and ``task=synthesize`` call :func:`derive_seed` with the same arguments for the same
window, so they produce the same motion; display names of characters never enter the seed
(the participant's role index does).
"""
from __future__ import annotations

import zlib

import numpy as np


def _word(x) -> int:
    if isinstance(x, str):
        return zlib.crc32(x.encode("utf-8"))
    return int(x) & 0xFFFFFFFF


def derive_seed(base: int, *, fold: int = 0, condition: str = "", session: str = "", window_frame: int = 0,
                role_index: int = 0) -> int:
    """A 31-bit seed from NumPy's SeedSequence over the given fields (stable across runs and machines).

    window_frame: the window's first frame in the session (not its index, so that an arbitrary
    window of ``task=synthesize`` seeds like the leave-one-out window starting at the same frame).
    """
    ss = np.random.SeedSequence([_word(base), _word(fold), _word(condition), _word(session),
                                 _word(window_frame), _word(role_index)])
    return int(ss.generate_state(1, np.uint32)[0] & 0x7FFFFFFF)
