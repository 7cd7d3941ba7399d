"""Text: the font (DejaVu Sans shipped with matplotlib) and fitting a label into a width."""
from __future__ import annotations

from pathlib import Path

import numpy as np


_FONTS: dict = {}


def _font(size: int, bold: bool = False):
    """DejaVu Sans (shipped with matplotlib) at ``size`` pixels; Pillow's default font without it."""
    from PIL import ImageFont

    key = (int(size), bool(bold))
    if key not in _FONTS:
        # the font file is found without importing matplotlib (its import costs about a second of a video)
        import importlib.util

        name = "DejaVuSans-Bold.ttf" if bold else "DejaVuSans.ttf"
        spec = importlib.util.find_spec("matplotlib")
        places = list(spec.submodule_search_locations or []) if spec is not None else []
        try:
            font = next(f for f in (Path(d) / "mpl-data" / "fonts" / "ttf" / name for d in places) if f.is_file())
            _FONTS[key] = ImageFont.truetype(str(font), int(size))
        except (StopIteration, OSError):   # pragma: no cover - matplotlib is a dependency
            _FONTS[key] = ImageFont.load_default(int(size))
    return _FONTS[key]


def _text_width(text: str, font) -> int:
    box = font.getbbox(text)
    return int(np.ceil(box[2] - min(box[0], 0)))


def _fit(text: str, font, width: int) -> str:
    """``text`` shortened with an ellipsis to at most ``width`` pixels."""
    if _text_width(text, font) <= width:
        return text
    while text and _text_width(text + "…", font) > width:
        text = text[:-1]
    return text + "…" if text else ""
