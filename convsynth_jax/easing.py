"""Easing curves: maps of a ramp weight w in [0, 1] onto [0, 1] with w(0) = 0 and w(1) = 1.

The one home for the blend and transition ramps of every system:

* :func:`linear`: w itself (Walk the Talk's Eq. 2 as printed);
* :func:`smoothstep`: 3w^2 - 2w^3, zero slope at both ends (the synthetic corpus's posture shifts,
  the planted test clips);
* :func:`smootherstep`: 6w^5 - 15w^4 + 10w^3, zero first and second derivatives at both ends (our
  Walk the Talk splice ramp, the rest easing of gestures cut from a synthesized conversation);
* :func:`cosine`: 0.5 - 0.5 cos(pi t / length), the cross-fade of the motion graph's transitions
  (synth/realize.py).

:data:`EASES` names them for configuration (``walktalk.splice.ease``). Plain NumPy, float64.
"""
from __future__ import annotations

import numpy as np


def linear(w):
    """w unchanged."""
    return w


def smoothstep(w):
    """3w^2 - 2w^3 (zero slope at 0 and 1); w in [0, 1] (clip first)."""
    return w * w * (3 - 2 * w)


def smootherstep(w):
    """6w^5 - 15w^4 + 10w^3 (zero first and second derivatives at 0 and 1); w in [0, 1]."""
    return w * w * w * (w * (6 * w - 15) + 10)


def cosine(t, length=1.0):
    """0.5 - 0.5 cos(pi t / length): rises from 0 at t = 0 to 1 at t = length."""
    return 0.5 - 0.5 * np.cos(np.pi * t / length)


EASES = {"linear": linear, "smoothstep": smoothstep, "smootherstep": smootherstep, "cosine": cosine}
