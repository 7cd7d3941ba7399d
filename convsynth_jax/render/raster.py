"""Rasterization: capsules and discs in painter's order, drawn by Pillow at SUPERSAMPLE x SUPERSAMPLE samples
per pixel and box-filtered down (``convsynth_jax.testing.render_reference`` is its per-pixel reference)."""
from __future__ import annotations

import numpy as np

from ..errors import ConvSynthError
from .bodies import _facing, stature
from .camera import Camera, _project, three_quarter_camera
from .style import BACKGROUND_FLOOR, BACKGROUND_TOP, BODY_RGB, HAND_RADIUS, HEAD_LIFT, HEAD_RADIUS, LIMB_RADIUS, NOSE_RGB, SKIN_RGB, TORSO_RADIUS


SUPERSAMPLE = 2     # primitives are drawn at this many times the panel's size, then box-filtered down


def _background(width: int, height: int, floor_row: float):
    """The panel's backdrop (a Pillow image at SUPERSAMPLE times ``width`` x ``height``): wall above
    ``floor_row``, floor below."""
    from PIL import Image, ImageDraw

    ss = SUPERSAMPLE
    im = Image.new("RGB", (width * ss, height * ss), BACKGROUND_TOP)
    fr = int(np.clip(floor_row, 0, height))
    if fr < height:
        ImageDraw.Draw(im).rectangle([0, fr * ss, width * ss - 1, height * ss - 1], fill=BACKGROUND_FLOOR)
    return im


def _primitives(bodies, frame: int, cam: Camera, width: int, height: int) -> list:
    """(depth, p0, p1, radius, rgb, body index) of every capsule (bone) and disc (head, nose, hands;
    p0 == p1) of ``bodies`` at ``frame``; points are (col, row) panel pixels, radius in pixels. A bone
    that starts where a bone at least as thick ends has its radius negated: its start needs no disc
    (the other's end disc covers the joint; :func:`rasterize` draws one less disc)."""
    prims = []
    y = np.array([0.0, 1.0, 0.0])
    sizes = [stature(b) for b in bodies]
    skin, nose = np.asarray(SKIN_RGB, np.float32), np.asarray(NOSE_RGB, np.float32)
    for k, b in enumerate(bodies):
        f = min(frame, b.num_frames - 1)
        col, row, depth = _project(cam, b.positions[f], width, height)
        size = sizes[k]
        px = cam.scale * size
        base = np.asarray(BODY_RGB[(k if b.color is None else b.color) % len(BODY_RGB)], np.float32)
        bone_depth, radius = {}, {}
        for j, q in enumerate(b.parents):
            if q >= 0:
                radius[j] = max((TORSO_RADIUS if (j in b.torso and q in b.torso) else LIMB_RADIUS) * px, 1.0)
        for j, q in enumerate(b.parents):
            if q < 0:
                continue
            bone_depth[j] = 0.5 * (depth[j] + depth[q])
            r = radius[j] if radius.get(q, 0.0) < radius[j] else -radius[j]
            prims.append((bone_depth[j], (col[q], row[q]), (col[j], row[j]), r, base, k))

        def over(j, d):     # a disc at joint j is drawn over the bone that ends there
            return min(d, bone_depth.get(j, d)) - 1e-6 * (1.0 + abs(d))

        if b.head is not None:
            hw = np.asarray(b.positions[f, b.head], np.float64) + HEAD_LIFT * size * y
            hc, hr, hd = _project(cam, hw, width, height)
            rad = max(HEAD_RADIUS * px, 2.0)
            head_depth = over(b.head, float(hd))
            prims.append((head_depth, (float(hc), float(hr)), (float(hc), float(hr)), rad, skin, k))
            face = _facing(b, f)
            if face is not None:     # the nose: over the head when it faces the camera, behind it when it faces away
                nw = hw + HEAD_RADIUS * size * face
                nc, nr, nd = _project(cam, nw, width, height)
                prims.append((head_depth + float(nd - hd), (float(nc), float(nr)), (float(nc), float(nr)),
                              max(0.32 * rad, 1.0), nose, k))
        for j in b.hands:
            prims.append((over(j, depth[j]), (col[j], row[j]), (col[j], row[j]), max(HAND_RADIUS * px, 1.5), skin, k))
    return prims


def painter_order(prims) -> list:
    """``prims`` far to near, each with its colour shaded by its depth (nearer: brighter) as integers:
    [(p0, p1, radius, rgb)]."""
    if not prims:
        return []
    ds = np.array([p[0] for p in prims])
    lo, hi = ds.min(), ds.max()
    out = []
    for i in np.argsort(-ds, kind="stable"):
        d, p0, p1, r, rgb, _ = prims[i]
        shade = 0.78 + 0.22 * (hi - d) / (hi - lo + 1e-9)
        out.append((p0, p1, float(r), tuple(int(c * shade + 0.5) for c in rgb)))
    return out


class Backdrop:
    """A panel's backdrop (:func:`_background`) at SUPERSAMPLE times its size and box-filtered down
    once: the samples primitives are drawn over, and the pixels where there are none."""

    def __init__(self, samples):
        self.samples = samples
        self.pixels = np.asarray(samples.reduce(SUPERSAMPLE) if SUPERSAMPLE > 1 else samples, np.uint8)


def rasterize(shapes, background) -> np.ndarray:
    """Draw ``shapes`` [(p0, p1, radius, rgb)] in order (later over earlier) over ``background`` (a
    :class:`Backdrop`, or a Pillow image at SUPERSAMPLE times the panel) and box-filter the result down:
    uint8 (H, W, 3). A capsule is a line of width 2 radius with a disc at each end (Pillow's C drawing
    at SUPERSAMPLE x SUPERSAMPLE samples per pixel: the anti-aliasing); a disc when p0 == p1; a
    negative radius leaves out the start's disc (a joint another shape already rounds). Only the
    shapes' bounding box is drawn and filtered (the rest is the backdrop's own pixels). The slow
    reference is ``convsynth_jax.testing.render_reference.rasterize_reference`` (coverage of each
    pixel's sample points, per pixel)."""
    from PIL import ImageDraw

    if not isinstance(background, Backdrop):
        background = Backdrop(background)
    ss = SUPERSAMPLE
    out = background.pixels.copy()
    h, w = out.shape[:2]
    if not shapes:
        return out
    xs = [v for p0, p1, r, _ in shapes for v in (p0[0] - abs(r), p1[0] - abs(r), p0[0] + abs(r), p1[0] + abs(r))]
    ys = [v for p0, p1, r, _ in shapes for v in (p0[1] - abs(r), p1[1] - abs(r), p0[1] + abs(r), p1[1] + abs(r))]
    c0, c1 = max(int(np.floor(min(xs))) - 1, 0), min(int(np.ceil(max(xs))) + 2, w)
    r0, r1 = max(int(np.floor(min(ys))) - 1, 0), min(int(np.ceil(max(ys))) + 2, h)
    if c0 >= c1 or r0 >= r1:
        return out
    im = background.samples.crop((c0 * ss, r0 * ss, c1 * ss, r1 * ss))
    d = ImageDraw.Draw(im)
    ox, oy = c0 * ss, r0 * ss
    for p0, p1, r, rgb in shapes:
        c = rgb if type(rgb) is tuple and type(rgb[0]) is int else tuple(int(round(float(v))) for v in rgb)
        x0, y0, x1, y1 = ss * p0[0] - ox, ss * p0[1] - oy, ss * p1[0] - ox, ss * p1[1] - oy
        rr = ss * abs(r)
        if (x1 - x0) ** 2 + (y1 - y0) ** 2 > 1e-6:
            d.line([(x0, y0), (x1, y1)], fill=c, width=max(1, int(round(2 * rr))))
            d.ellipse([x1 - rr, y1 - rr, x1 + rr - 1, y1 + rr - 1], fill=c)    # Pillow's box includes its last sample
            if r < 0:
                continue
        d.ellipse([x0 - rr, y0 - rr, x0 + rr - 1, y0 + rr - 1], fill=c)
    out[r0:r1, c0:c1] = np.asarray(im.reduce(ss) if ss > 1 else im, np.uint8)
    return out


def draw_panel(bodies, frame: int, cam: Camera, width: int, height: int, background) -> np.ndarray:
    """One panel (H, W, 3 uint8) of ``bodies`` at ``frame`` over ``background`` (a :class:`Backdrop`)."""
    return rasterize(painter_order(_primitives(bodies, frame, cam, width, height)), background)


class PanelRenderer:
    """Panels under one camera fitted to all of ``scenes`` (lists of bodies, one list per panel that
    will be drawn), so every panel of a scene is framed alike. ``draw(bodies, frame)``: uint8
    (height, width, 3); ``frames(bodies)``: every ``step``-th frame."""

    def __init__(self, scenes, width: int, height: int, step: int = 1, yaw_deg: float = 35.0, pitch_deg: float = 12.0,
                 across=None):
        allb = [b for sc in scenes for b in sc]
        if not allb:
            raise ConvSynthError("nothing to render: no body")
        self.width, self.height, self.step = int(width), int(height), max(1, int(step))
        self.cam = three_quarter_camera(allb, self.width, self.height, yaw_deg, pitch_deg, across=across)
        feet = min(_project(self.cam, b.positions[0], self.width, self.height)[1].max() for b in allb)
        self.bg = Backdrop(_background(self.width, self.height, feet - 0.02 * self.height))

    def draw(self, bodies, frame: int) -> np.ndarray:
        return draw_panel(bodies, frame, self.cam, self.width, self.height, self.bg)

    def frames(self, bodies) -> list:
        if not bodies:
            raise ConvSynthError("nothing to render: a panel without bodies")
        n = min(b.num_frames for b in bodies)
        if all((b.positions == b.positions[:1]).all() for b in bodies):
            return [self.draw(bodies, 0)] * len(range(0, n, self.step))          # a frozen scene is drawn once
        return [self.draw(bodies, f) for f in range(0, n, self.step)]
