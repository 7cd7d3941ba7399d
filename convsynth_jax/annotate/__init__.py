"""Audio segmentation (phonemic clauses, listener responses, hesitations, F0 peaks) and motion segmentation."""
from .types import AUDIO_LABELS, HP, HYPOTHESES, IDLE, LR, MOTION_KINDS, PC, FrameAudio  # noqa: F401
