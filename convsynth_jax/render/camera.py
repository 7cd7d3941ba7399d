"""The orthographic camera: across the line between the characters, turned and tilted, fitted to every body."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConvSynthError
from .bodies import stature
from .style import HEAD_LIFT, HEAD_RADIUS


@dataclass(frozen=True)
class Camera:
    """Orthographic: screen right, screen up and view direction (unit 3-vectors), the world point at
    the panel's centre and pixels per world unit."""

    right: np.ndarray
    up: np.ndarray
    view: np.ndarray
    center: np.ndarray
    scale: float


def _across(bodies) -> np.ndarray:
    """The horizontal unit vector that is screen right before the yaw: from the first body to the
    second (by their mean roots); one body (or two in one place): the body's left, so the camera sees
    its front; no shoulders or hands to tell: +X."""
    roots = [np.asarray(b.positions[:, 0, :], np.float64).mean(0) for b in bodies]
    size = max(stature(b) for b in bodies)
    for r in roots[1:]:
        d = r - roots[0]
        d[1] = 0.0
        if np.linalg.norm(d) > 0.1 * size:
            return d / np.linalg.norm(d)
    b = bodies[0]
    pair = b.shoulders if len(b.shoulders) == 2 else b.hands if len(b.hands) == 2 else None
    if pair is not None:
        d = np.asarray(b.positions[:, pair[0]] - b.positions[:, pair[1]], np.float64).mean(0)   # left - right
        d[1] = 0.0
        if np.linalg.norm(d) > 1e-9:
            return d / np.linalg.norm(d)
    return np.array([1.0, 0.0, 0.0])


def three_quarter_camera(bodies, width: int, height: int, yaw_deg: float = 35.0, pitch_deg: float = 12.0,
                         margin: float = 0.05, across=None) -> Camera:
    """A camera that sees ``bodies`` (all frames) from the side view across the characters turned
    ``yaw_deg`` about the vertical and tilted ``pitch_deg`` down, scaled so they (heads included) fit
    a ``width`` x ``height`` panel with ``margin`` on every side. ``across``: the horizontal direction
    that is screen right before the yaw (None: from the first character to the second, :func:`_across`)."""
    if not bodies:
        raise ConvSynthError("nothing to render: no body")
    if across is None:
        e_h = _across(bodies)
    else:
        e_h = np.array([float(across[0]), 0.0, float(across[2])])
        if np.linalg.norm(e_h) < 1e-9:
            raise ConvSynthError(f"the camera's across direction must be horizontal, got {tuple(across)}")
        e_h /= np.linalg.norm(e_h)
    y = np.array([0.0, 1.0, 0.0])
    e_g = np.cross(e_h, y)            # right-handed: the side view looks along -e_g
    a, p = np.radians(yaw_deg), np.radians(pitch_deg)
    right = np.cos(a) * e_h + np.sin(a) * e_g
    fwd = np.sin(a) * e_h - np.cos(a) * e_g
    view = np.cos(p) * fwd - np.sin(p) * y
    up = np.cos(p) * y + np.sin(p) * fwd
    pts = []
    for b in bodies:
        sub = np.asarray(b.positions[:: max(1, b.num_frames // 60)], np.float64)
        drawn = [j for j, q in enumerate(b.parents) if q != -2]
        pts.append(sub[:, drawn].reshape(-1, 3))
        if b.head is not None:      # the head disc's top
            s = stature(b)
            pts.append(sub[:, b.head] + (HEAD_LIFT + HEAD_RADIUS) * s * y)
    pts = np.concatenate(pts)
    xs, ys = pts @ right, pts @ up
    cx, cy = 0.5 * (xs.min() + xs.max()), 0.5 * (ys.min() + ys.max())
    span_x, span_y = max(xs.max() - xs.min(), 1e-6), max(ys.max() - ys.min(), 1e-6)
    scale = min(width * (1 - 2 * margin) / span_x, height * (1 - 2 * margin) / span_y)
    return Camera(right, up, view, cx * right + cy * up, float(scale))


def _project(cam: Camera, pts: np.ndarray, width: int, height: int):
    """(col, row, depth) arrays of world points ``pts`` (..., 3)."""
    q = np.asarray(pts, np.float64) - cam.center
    col = width / 2 + cam.scale * (q @ cam.right)
    row = height / 2 - cam.scale * (q @ cam.up)
    return col, row, q @ cam.view
