"""The one way a figure reaches a file: :func:`convsynth_jax.utils.save_figure` (in the foundation
layer, so a method's own figure, such as a model's loss curve, is written the same way)."""
from __future__ import annotations

from ..utils import save_figure

__all__ = ["save_figure"]
