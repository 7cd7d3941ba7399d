"""Study videos: two panels side by side (left and right condition), each with both characters drawn
from a three-quarter view with thick limbs, a head and hands, and the window's audio muxed in
(H.264 + AAC, through the ffmpeg binary of ``imageio-ffmpeg`` as :func:`convsynth_jax.render.render_video`).

The paper's viewers saw skinned characters (Section 8.1, rendered in SpireEngine); a thin side-view
stick figure hides the depth of gestures. Here every bone is a capsule and the head and hands are
discs, drawn far to near (painter's order) with an orthographic camera turned ``yaw_deg`` about the
vertical from the side view and tilted ``pitch_deg`` down; nearer parts are drawn brighter. Sizes are
fractions of the body's height, so any unit (cm, m) renders alike. Rasterization is NumPy (each
primitive fills its bounding box with an anti-aliased edge): about 13 ms per 320 x 360 panel of two
bodies with 21 bones each (load 4 on 2 cores). ``task=study_build`` draws each condition's panels of
a segment once (:class:`PanelRenderer`, one camera per segment) and reuses them in every pair.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import ConvSynthError
from ..render import write_mp4

log = logging.getLogger(__name__)

BODY_RGB = ((52, 92, 168), (186, 84, 52))      # character 0, character 1
SKIN_RGB = (233, 196, 160)
BACKGROUND_TOP, BACKGROUND_FLOOR = (236, 238, 242), (205, 203, 198)


@dataclass(frozen=True)
class DrawnBody:
    """One character to draw. positions: (frames, joints, 3) world positions (Y up); parents:
    (joints,) parent index (-1 root); head, hands: joint indices (None where the rig has none);
    torso: indices of joints on the root-to-head chain (their bones are drawn thicker)."""

    positions: np.ndarray
    parents: tuple[int, ...]
    head: int | None
    hands: tuple[int, ...]
    torso: frozenset


def body_from_motion(motion) -> DrawnBody:
    """A :class:`DrawnBody` from a :class:`~convsynth_jax.skeleton.Motion` (forward kinematics and the
    rig's roles, :func:`convsynth_jax.rig.find_role`). Joints below a hand (fingers) are dropped:
    the hand disc stands for them."""
    from ..kinematics import forward_kinematics
    from ..rig import find_role

    sk = motion.skeleton
    pos = np.asarray(forward_kinematics(motion), dtype=np.float32)
    parents = tuple(int(p) for p in sk.parents)
    head = find_role(sk, "head")
    hands = tuple(j for j in (find_role(sk, "left_hand"), find_role(sk, "right_hand")) if j is not None)
    torso = set()
    j = head if head is not None else int(np.argmax(pos[0, :, 1]))
    while j >= 0:
        torso.add(j)
        j = parents[j]
    below_hand = set()
    for j in range(len(parents)):
        q = parents[j]
        while q >= 0:
            if q in hands:
                below_hand.add(j)
                break
            q = parents[q]
    kept = tuple(-2 if j in below_hand else p for j, p in enumerate(parents))   # -2: not drawn
    return DrawnBody(pos, kept, head, hands, frozenset(torso))


def frozen(body: DrawnBody, frame: int = 0) -> DrawnBody:
    """``body`` held at ``frame`` for its whole length (attention checks)."""
    pos = np.repeat(body.positions[frame:frame + 1], body.positions.shape[0], axis=0)
    return DrawnBody(pos, body.parents, body.head, body.hands, body.torso)


@dataclass(frozen=True)
class Camera:
    """Orthographic: screen right, screen up and view direction (unit 3-vectors), the world point at
    the panel's centre and pixels per world unit."""

    right: np.ndarray
    up: np.ndarray
    view: np.ndarray
    center: np.ndarray
    scale: float


def three_quarter_camera(bodies, width: int, height: int, yaw_deg: float = 35.0, pitch_deg: float = 12.0,
                         margin: float = 0.06) -> Camera:
    """A camera that sees ``bodies`` (all frames) from the side view (across the axis joining the
    characters' roots) turned ``yaw_deg`` about the vertical and tilted ``pitch_deg`` down, scaled
    so they fit a ``width`` x ``height`` panel with ``margin`` on every side."""
    roots = np.concatenate([b.positions[:, 0, :] for b in bodies])
    spread = roots.max(0) - roots.min(0)
    e_h = np.array([0.0, 0.0, 1.0]) if spread[2] > spread[0] else np.array([1.0, 0.0, 0.0])
    y = np.array([0.0, 1.0, 0.0])
    e_g = np.cross(e_h, y)            # right-handed: the side view looks along -e_g
    a, p = np.radians(yaw_deg), np.radians(pitch_deg)
    right = np.cos(a) * e_h + np.sin(a) * e_g
    fwd = np.sin(a) * e_h - np.cos(a) * e_g
    view = np.cos(p) * fwd - np.sin(p) * y
    up = np.cos(p) * y + np.sin(p) * fwd
    pts = np.concatenate([b.positions[:: max(1, b.positions.shape[0] // 30)].reshape(-1, 3) for b in bodies]).astype(np.float64)
    xs, ys = pts @ right, pts @ up
    center = np.zeros(3)
    cx, cy = 0.5 * (xs.min() + xs.max()), 0.5 * (ys.min() + ys.max())
    center = cx * right + cy * up
    span_x, span_y = max(xs.max() - xs.min(), 1e-6), max(ys.max() - ys.min(), 1e-6)
    scale = min(width * (1 - 2 * margin) / span_x, height * (1 - 2 * margin) / span_y)
    return Camera(right, up, view, center, float(scale))


def _project(cam: Camera, pts: np.ndarray, width: int, height: int):
    """(col, row, depth) arrays of world points ``pts`` (..., 3)."""
    q = pts.astype(np.float64) - cam.center
    col = width / 2 + cam.scale * (q @ cam.right)
    row = height / 2 - cam.scale * (q @ cam.up)
    return col, row, q @ cam.view


def _capsule(img: np.ndarray, p0, p1, radius: float, rgb: np.ndarray) -> None:
    """Blend a capsule (segment p0-p1 of ``radius`` pixels, (col, row) points) into ``img`` (H, W, 3
    float32) with a one-pixel anti-aliased edge. A disc when p0 == p1."""
    h, w = img.shape[:2]
    c0 = int(max(np.floor(min(p0[0], p1[0]) - radius - 1), 0))
    c1 = int(min(np.ceil(max(p0[0], p1[0]) + radius + 2), w))
    r0 = int(max(np.floor(min(p0[1], p1[1]) - radius - 1), 0))
    r1 = int(min(np.ceil(max(p0[1], p1[1]) + radius + 2), h))
    if c0 >= c1 or r0 >= r1:
        return
    cc = np.arange(c0, c1, dtype=np.float32)[None, :] + 0.5
    rr = np.arange(r0, r1, dtype=np.float32)[:, None] + 0.5
    dx, dy = p1[0] - p0[0], p1[1] - p0[1]
    n2 = dx * dx + dy * dy
    if n2 > 1e-9:
        t = np.clip(((cc - p0[0]) * dx + (rr - p0[1]) * dy) / n2, 0.0, 1.0)
    else:
        t = np.zeros((1, 1), np.float32)
    ex, ey = cc - (p0[0] + t * dx), rr - (p0[1] + t * dy)
    alpha = np.clip(radius + 0.5 - np.sqrt(ex * ex + ey * ey), 0.0, 1.0)[..., None]
    patch = img[r0:r1, c0:c1]
    patch *= 1.0 - alpha
    patch += alpha * rgb


def _background(width: int, height: int, floor_row: float) -> np.ndarray:
    img = np.empty((height, width, 3), np.float32)
    img[:] = BACKGROUND_TOP
    fr = int(np.clip(floor_row, 0, height))
    img[fr:] = BACKGROUND_FLOOR
    return img


def draw_panel(bodies, frame: int, cam: Camera, width: int, height: int, background: np.ndarray) -> np.ndarray:
    """One panel (H, W, 3 float32) of ``bodies`` at ``frame``: primitives sorted far to near."""
    img = background.copy()
    prims = []     # (depth, p0, p1, radius, rgb)
    for k, b in enumerate(bodies):
        f = min(frame, b.positions.shape[0] - 1)
        col, row, depth = _project(cam, b.positions[f], width, height)
        height_px = cam.scale * float(np.ptp(b.positions[0, :, 1]) or 1.0)
        base = np.asarray(BODY_RGB[k % len(BODY_RGB)], np.float32)
        for j, q in enumerate(b.parents):
            if q < 0:
                continue
            r = (0.045 if (j in b.torso and q in b.torso) else 0.026) * height_px
            prims.append((0.5 * (depth[j] + depth[q]), (col[q], row[q]), (col[j], row[j]), max(r, 1.0), base))
        skin = np.asarray(SKIN_RGB, np.float32)
        if b.head is not None:
            hp = (col[b.head], row[b.head] - 0.04 * height_px)
            prims.append((depth[b.head] - 1e-3, hp, hp, max(0.075 * height_px, 2.0), skin))
        for j in b.hands:
            prims.append((depth[j] - 1e-3, (col[j], row[j]), (col[j], row[j]), max(0.034 * height_px, 1.5), skin))
    if not prims:
        return img
    ds = np.array([p[0] for p in prims])
    lo, hi = ds.min(), ds.max()
    for i in np.argsort(-ds, kind="stable"):
        d, p0, p1, r, rgb = prims[i]
        shade = 0.72 + 0.28 * (hi - d) / (hi - lo + 1e-9)      # nearer: brighter
        _capsule(img, p0, p1, r, rgb * shade)
    return img


class PanelRenderer:
    """Panels of one scene (e.g. one segment in every condition) under one camera, fitted to all of
    ``bodies`` (lists of bodies, one list per panel that will be drawn), so every stimulus of a
    segment is framed alike. ``frames(bodies)``: uint8 (height, width, 3) images, every ``step``-th frame."""

    def __init__(self, scenes, width: int, height: int, step: int = 1, yaw_deg: float = 35.0, pitch_deg: float = 12.0):
        allb = [b for sc in scenes for b in sc]
        if not allb:
            raise ConvSynthError("a study video needs bodies to draw")
        self.width, self.height, self.step = int(width), int(height), max(1, int(step))
        self.cam = three_quarter_camera(allb, width, height, yaw_deg, pitch_deg)
        feet = min(_project(self.cam, b.positions[0], width, height)[1].max() for b in allb)
        self.bg = _background(width, height, feet - 0.02 * height)

    def frames(self, bodies) -> list:
        if not bodies:
            raise ConvSynthError("a study video needs bodies in both panels")
        n = min(b.positions.shape[0] for b in bodies)
        if all((b.positions == b.positions[:1]).all() for b in bodies):
            still = draw_panel(bodies, 0, self.cam, self.width, self.height, self.bg).clip(0, 255).astype(np.uint8)
            return [still] * len(range(0, n, self.step))          # a frozen scene is drawn once
        return [draw_panel(bodies, f, self.cam, self.width, self.height, self.bg).clip(0, 255).astype(np.uint8)
                for f in range(0, n, self.step)]


def join_panels(left: list, right: list):
    """Side-by-side frames (height, 2 * width + 2, 3) of two panel sequences (a 2-pixel divider)."""
    n = min(len(left), len(right))
    if n == 0:
        raise ConvSynthError("nothing to render: an empty panel sequence")
    gap = np.full((left[0].shape[0], 2, 3), 60, np.uint8)
    for i in range(n):
        yield np.ascontiguousarray(np.concatenate([left[i], gap, right[i]], axis=1))


def side_by_side_frames(left, right, width: int, height: int, step: int = 1, yaw_deg: float = 35.0, pitch_deg: float = 12.0):
    """Frames (height, 2 * width + 2 gap, 3) uint8 of the ``left`` and ``right`` bodies (one camera
    for both panels, fitted to all bodies), every ``step``-th frame. Width and height even."""
    if not left or not right:
        raise ConvSynthError("a study video needs bodies in both panels")
    r = PanelRenderer([left, right], width, height, step, yaw_deg, pitch_deg)
    yield from join_panels(r.frames(left), r.frames(right))


def write_video(frames, fps: float, path: str | Path, audio: str | Path | None = None) -> Path:
    """Write ``frames`` (an iterable of uint8 (H, W, 3), even H and W) to ``path``: MP4, H.264 yuv420p
    with ``+faststart``, plus the WAV ``audio`` as AAC when given. Written atomically."""
    path = Path(path)
    gen = iter(frames)
    first = next(gen)
    if first.shape[0] % 2 or first.shape[1] % 2:
        raise ConvSynthError(f"H.264 frames need an even width and height, got {first.shape[1]} x {first.shape[0]}", path)
    return write_mp4(path, first, gen, fps, audio, macro_block_size=2, codec="libx264", pix_fmt_out="yuv420p",
                     output_params=["-movflags", "+faststart"])


def render_pair_video(left, right, fps: float, path: str | Path, audio: str | Path | None = None, width: int = 320,
                      height: int = 360, render_fps: float = 15.0, yaw_deg: float = 35.0, pitch_deg: float = 12.0) -> Path:
    """Write ``path`` (MP4, H.264 yuv420p + AAC when ``audio`` is a WAV), the ``left`` and ``right``
    bodies (motion at ``fps``) side by side, drawn at about ``render_fps``. Written atomically."""
    if width % 2 or height % 2:
        raise ConvSynthError(f"study video panels need an even width and height, got {width} x {height}")
    step = max(1, int(round(fps / render_fps)))
    return write_video(side_by_side_frames(left, right, width, height, step, yaw_deg, pitch_deg), fps / step, path, audio)
