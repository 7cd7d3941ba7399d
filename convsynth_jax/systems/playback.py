"""Diagnostics of systems that play back training frames (the motion graph, random playback).

Their output has per-frame provenance (``WindowResult.source_clip`` / ``source_frame``: the training
clip and frame each output frame shows). They answer two hooks of the interface:

- ``window_diagnostics``: every audio constraint of the window (whatever the condition) recomputed by the
  search's independent checker (``search/check.py``) from the source clips' per-frame audio labels:
  ``all_constraints_total`` / ``all_constraints_met``, ``checker_matching`` and per kind
  ``checker_<kind>_met`` / ``_total`` (the registry's kinds, :mod:`convsynth_jax.annotate.kinds`).
- ``source_positions``: the joint positions of a whole source clip, from which the evaluation
  computes ``seam_content_ratio`` (what the source clips bring to the seams by themselves); forward
  kinematics runs once per clip and the system keeps the positions for the sweep.

A playback model carries ``motions`` (clip name -> Motion) and ``labels`` (clip name -> (own, partner)
FrameAudio) of its training clips.
"""
from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from ..annotate.kinds import constraint_kinds
from .base import SynthesisSystem, WindowInput, WindowResult


def clip_name(session: str, role: str) -> str:
    """Name of one participant's recording among a model's training clips (and inside a motion graph)."""
    return f"{session}_{role}"


def training_labels(clips) -> dict:
    """clip name -> (own, partner) per-frame audio labels of ``clips`` (ParticipantAnnotation records)."""
    return {clip_name(c.session, c.role): (c.own, c.partner) for c in clips}


class PlaybackSystem(SynthesisSystem):
    """A system whose output frames are training frames (see the module docstring)."""

    def __init__(self, params, system):
        super().__init__(params, system)
        # clip name -> (Motion, (F, J, 3) float32 positions): each source clip's once for the whole sweep
        self._source_positions: dict = {}

    def window_diagnostics(self, model: Any, window: WindowInput, result: WindowResult) -> dict:
        labels: Mapping = getattr(model, "labels", None) or {}
        if result.source_clip is None or not all(c in labels for c in result.source_clip):
            return {}
        from ..search.check import check_path

        sp = self.params.search
        chk = check_path(list(result.source_clip), [int(f) for f in result.source_frame], labels,
                         window.own_segments, window.partner_segments, window.fps, float(sp.tolerance),
                         matching=sp.matching, warp=result.diagnostics.get("warp"))
        row = {"all_constraints_total": chk["total"], "all_constraints_met": chk["met"], "checker_matching": sp.matching}
        for kind in constraint_kinds():
            d = [x["met"] for x in chk["details"] if x["kind"] == kind.name]
            row[f"checker_{kind.name}_met"], row[f"checker_{kind.name}_total"] = int(sum(d)), len(d)
        return row

    def source_positions(self, model: Any, clip: str) -> np.ndarray | None:
        """(F, J, 3) float64 global joint positions of the whole training clip ``clip``, by the padded
        forward kinematics of graph construction (one compile per power of two); computed once per
        clip and kept while the clip's Motion is the same object."""
        motion = (getattr(model, "motions", None) or {}).get(clip)
        if motion is None:
            return None
        hit = self._source_positions.get(clip)
        if hit is None or hit[0] is not motion:
            from ..kinematics import padded_global_transforms

            pos, _, n = padded_global_transforms([motion])
            hit = self._source_positions[clip] = (motion, np.asarray(pos)[:n])
        return np.asarray(hit[1], np.float64)
