"""Parameters of the realization (paper Section 7.3); ``conf/synth``."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class SynthParams:
    blend_frames: int = 6   # cosine blend length after a synthetic transition
