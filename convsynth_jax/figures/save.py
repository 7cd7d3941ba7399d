"""The one way a figure reaches a file."""
from __future__ import annotations

from pathlib import Path

from ..utils import atomic_path


def save_figure(fig, path, dpi: int = 110) -> Path:
    """Write matplotlib Figure ``fig`` to ``path`` in the format its suffix names (png, pdf, svg),
    at ``dpi``; atomically (a temporary file renamed onto ``path``), so a failed write leaves no
    half-written figure. Returns the path."""
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=dpi, format=path.suffix.lstrip(".").lower() or "png")
    return path
