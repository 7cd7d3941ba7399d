"""Parameters of the realization (paper Section 7.3); ``conf/synth``."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class SynthParams:
    # cosine blend length after a synthetic transition (the paper gives none; ours: 12 frames = 0.4 s at
    # 30 fps; on leave-one-out fold 0 the largest seam_ratio was 1.87 with 6 frames, 0.84 with 12)
    blend_frames: int = 12
