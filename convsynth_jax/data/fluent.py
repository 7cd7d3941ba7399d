"""Fluent synthetic speech: clauses joined without pauses, for measuring prosodic clause
segmentation where pauses say nothing.

One speaker's clauses of given sizes, every word followed by an ordinary word gap (30-70 ms, also
between clauses), the last word of each clause lengthened, rendered with the synthetic corpus's voice
(``data/synthetic/voice.py``: declination across each clause, so F0 resets at every clause boundary, and a
pitch accent on one random word, the planted stressed word and F0 peak).
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from ..io.audio import Audio
from .synthetic import VOCAB, Segment, _render_voice


def fluent_speech(seed: int, sizes, f0_base: float = 150.0, sample_rate: int = 16000, lengthening: float = 1.3,
                  accent_rise: float = 0.28):
    """(audio, words DataFrame[start, end, word], planted clauses [Segment with start, peak, end,
    words]) for clauses of ``sizes`` words (module docstring); deterministic in ``seed``."""
    rng = np.random.default_rng(seed)
    t, segs, words = 0.3, [], []
    for n in sizes:
        ws, w0 = [], t
        for i in range(int(n)):
            d = rng.uniform(0.2, 0.34) * (lengthening if i == n - 1 else 1.0)
            ws.append([t, t + d, VOCAB[rng.integers(len(VOCAB))], False])
            t += d + rng.uniform(0.03, 0.07)
        t = ws[-1][1]
        k = int(rng.integers(n))
        ws[k][3] = True
        segs.append(Segment("speaker", "PC", w0, t, 0.5 * (ws[k][0] + ws[k][1]), [tuple(w) for w in ws]))
        words += [tuple(w[:3]) for w in ws]
        t += rng.uniform(0.03, 0.07)
    x, _ = _render_voice(segs, f0_base, t + 0.5, sample_rate, rng, accent_rise)
    return (Audio(x.astype(np.float32), sample_rate), pd.DataFrame(words, columns=["start", "end", "word"]), segs)
