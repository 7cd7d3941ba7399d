"""Slow, obvious reference of the renderer's rasterizer (:func:`convsynth_jax.render.rasterize`):
per output pixel, per sample point (SUPERSAMPLE x SUPERSAMPLE points at the centres of the pixel's
sub-squares), the colour of the last shape whose distance from the point is at most its radius (the
backdrop's sample where none), averaged over the samples."""
from __future__ import annotations

import numpy as np


def _distance(px, py, p0, p1) -> float:
    dx, dy = p1[0] - p0[0], p1[1] - p0[1]
    n2 = dx * dx + dy * dy
    t = 0.0 if n2 <= 1e-12 else min(max(((px - p0[0]) * dx + (py - p0[1]) * dy) / n2, 0.0), 1.0)
    return float(np.hypot(px - (p0[0] + t * dx), py - (p0[1] + t * dy)))


def rasterize_reference(shapes, backdrop: np.ndarray, ss: int) -> np.ndarray:
    """``shapes``: [(p0, p1, radius, rgb)] in drawing order, points as (col, row) in output pixels;
    ``backdrop``: (H * ss, W * ss, 3) the samples without shapes. Returns (H, W, 3) float64."""
    hs, ws = backdrop.shape[:2]
    h, w = hs // ss, ws // ss
    out = np.zeros((h, w, 3))
    for r in range(h):
        for c in range(w):
            acc = np.zeros(3)
            for a in range(ss):
                for b in range(ss):
                    x, y = c + (b + 0.5) / ss, r + (a + 0.5) / ss
                    colour = backdrop[r * ss + a, c * ss + b].astype(np.float64)
                    for p0, p1, radius, rgb in shapes:
                        if _distance(x, y, p0, p1) <= radius:
                            colour = np.round(np.asarray(rgb, np.float64))
                    acc += colour
            out[r, c] = acc / (ss * ss)
    return out
