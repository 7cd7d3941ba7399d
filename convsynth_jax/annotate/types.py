"""Shared annotation vocabulary: audio segment kinds, motion event kinds, per-frame label arrays.

Audio labels per frame (own channel and partner channel) use the integer codes of the registry
(:mod:`convsynth_jax.annotate.kinds`) everywhere (annotation, graph states, search constraints):
    IDLE = 0, PC (phonemic clause) = 1, LR (listener response) = 2, HP (hesitation pause) = 3.
"Partner hesitation" (PH) is the partner channel's HP.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# the label codes and the hypothesis table live in the registry (annotate/kinds.py)
from .kinds import (AUDIO_LABEL_NAMES, AUDIO_LABELS, HP, HYPOTHESES, IDLE, LR, MOTION_KINDS, PC,  # noqa: F401
                    audio_label_code)


@dataclass(frozen=True)
class FrameAudio:
    """Per-frame audio status of one channel at the motion frame rate (F frames).

    label: (F,) int8 codes; seg_start, seg_end, seg_peak: (F,) int32 frame indices of the segment the
    frame lies in (start inclusive, end exclusive, peak = frame of the F0 maximum; -1 for idle frames).
    """

    label: np.ndarray
    seg_start: np.ndarray
    seg_end: np.ndarray
    seg_peak: np.ndarray

    @property
    def num_frames(self) -> int:
        return int(self.label.shape[0])

    @staticmethod
    def from_segments(segments, num_frames: int, fps: float) -> "FrameAudio":
        """segments: DataFrame with columns kind ('PC'|'LR'|'HP'), start, end, peak (seconds).
        Later segments overwrite earlier ones where they overlap."""
        label = np.zeros(num_frames, np.int8)
        s_arr = np.full(num_frames, -1, np.int32)
        e_arr = np.full(num_frames, -1, np.int32)
        p_arr = np.full(num_frames, -1, np.int32)
        for row in segments.itertuples(index=False):
            code = audio_label_code(row.kind)
            if code == IDLE:
                continue
            s = int(np.clip(round(row.start * fps), 0, num_frames))
            e = int(np.clip(round(row.end * fps), 0, num_frames))
            if e <= s:
                e = min(s + 1, num_frames)
            if s >= num_frames:
                continue
            peak = getattr(row, "peak", np.nan)
            pk = int(np.clip(round(peak * fps), s, e - 1)) if np.isfinite(peak) else -1
            label[s:e] = code
            s_arr[s:e], e_arr[s:e], p_arr[s:e] = s, e, pk
        return FrameAudio(label, s_arr, e_arr, p_arr)

    def slice(self, start: int, stop: int) -> "FrameAudio":
        """Frames [start, stop); segment indices are shifted to the slice (may fall outside it)."""
        def sh(a):
            a = a[start:stop].copy()
            a[a >= 0] -= start
            return a
        return FrameAudio(self.label[start:stop].copy(), sh(self.seg_start), sh(self.seg_end), sh(self.seg_peak))
