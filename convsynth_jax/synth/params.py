"""Parameters of the realization (paper Section 7.3); ``conf/synth``."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class SynthParams:
    # cosine blend length after a synthetic transition (the paper gives none; ours: 12 frames = 0.4 s at
    # 30 fps keeps the seam metric under the ground truth's largest acceleration far more often than 6)
    blend_frames: int = 12
