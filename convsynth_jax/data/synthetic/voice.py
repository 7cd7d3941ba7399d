"""The synthetic voice: a harmonic source through two formant resonators, with an F0 contour per
clause (declination plus a pitch accent on the stressed word, the clause's F0 peak)."""
from __future__ import annotations

import numpy as np
from scipy import signal

from .conversation import Segment


def _render_voice(segs: list[Segment], f0_base: float, duration: float, sr: int, rng: np.random.Generator,
                  accent_rise: float):
    """Signal (N,) and the planted F0 track (N,) (0 where unvoiced) of one participant."""
    n = int(round(duration * sr))
    f0 = np.zeros(n)
    env = np.zeros(n)
    for s in segs:
        s0, s1 = s.words[0][0], s.words[-1][1]
        for (w0, w1, _, stressed) in s.words:
            a, b = int(w0 * sr), min(int(w1 * sr), n)
            if b <= a:
                continue
            tt = np.arange(a, b) / sr
            rel = (tt - s0) / max(s1 - s0, 1e-3)
            if s.kind == "PC":
                contour = f0_base * (1.08 - 0.16 * rel)  # declination across the clause
                contour = contour * (1.0 + accent_rise * np.exp(-0.5 * ((tt - s.peak) / 0.07) ** 2))
            else:
                contour = f0_base * (0.92 + 0.06 * np.exp(-0.5 * ((tt - s.peak) / 0.1) ** 2))
            f0[a:b] = contour
            ramp = min(int(0.02 * sr), (b - a) // 2)
            e = np.ones(b - a)
            if ramp > 0:
                e[:ramp] = np.linspace(0, 1, ramp)
                e[-ramp:] = np.linspace(1, 0, ramp)
            env[a:b] = e * (1.0 if (s.kind != "PC" or stressed) else 0.75)
    voiced = np.flatnonzero(env > 0)
    out = rng.normal(0.0, 0.002, n)
    if voiced.size:
        phase = 2 * np.pi * np.cumsum(f0) / sr
        ph = phase[voiced]
        src = np.zeros(voiced.size)
        for h in range(1, 13):
            src += np.sin(h * ph) / h
        voice = np.zeros(n)
        voice[voiced] = src * env[voiced]
        for fc, bw in ((600.0, 120.0), (1500.0, 200.0)):  # two formant resonators
            r = np.exp(-np.pi * bw / sr)
            th = 2 * np.pi * fc / sr
            voice = voice + 0.5 * signal.lfilter([1 - r], [1, -2 * r * np.cos(th), r * r], voice)
        voice *= 0.25 / max(np.abs(voice).max(), 1e-9)
        out += voice
    return out, f0
