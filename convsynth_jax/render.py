"""One renderer for every video and image of motion: ``task=render``, the main job's window
animation and contact sheet, ``task=converse``'s ``conversation.mp4``, ``walktalk_demo``'s video and
the perceptual study's stimuli all draw through this module.

**Bodies.** Every bone is a capsule and the head and hands are discs (a small nose disc on the head
shows where the character faces), drawn far to near (painter's order) under an orthographic camera:
the side view across the line from the first character to the second (the first on the left; one
character alone is seen from the front), turned ``yaw_deg`` about the vertical and tilted
``pitch_deg`` down; nearer parts are drawn brighter. Sizes are fractions of the body's *stature*
(bone lengths from the feet to the head, so a seated and a standing character are drawn alike, and
any unit renders alike). The paper's viewers saw skinned characters (Section 8.1); a thin side-view
stick figure hides the depth of gestures. Rasterization (:func:`rasterize`) is Pillow's C drawing
at SUPERSAMPLE x SUPERSAMPLE samples per pixel, box-filtered down, over the bodies' bounding box
only; ``convsynth_jax.testing.render_reference`` is its per-pixel reference. A body keeps its
colour all the time.

**Frames** (:class:`FrameRenderer`): panels side by side (e.g. synthesized | ground truth), one
camera fitted to every body of every panel, the panels' titles and the clock in a header, and under
them a timeline (:class:`TimelineStrip`): one row per :class:`Timeline` (a speaker's audio labels,
PC, LR, HP, with the kind written in the bar where it fits, and the synthetic transitions as ticks
under the bars), the speakers' names in a gutter whose width is measured from the names, a time
axis and a legend of the kinds shown. A timeline longer than ``timeline_span_s`` scrolls: it is
drawn once at a fixed scale and cropped around the cursor, so labels stay readable on an input of
any length. Static parts (header, gutter, legend, the whole strip) are drawn once with Pillow;
per frame only the panels, the strip's crop, the cursor and the clock.

**Files.** :func:`render_video` (H.264 MP4 with the WAV muxed in as AAC, through the ffmpeg binary of
``imageio-ffmpeg``: no system ffmpeg needed), :func:`render_animation` (GIF on one palette, or MP4),
:func:`contact_sheet` (PNG: evenly spaced frames of every panel above the whole timeline with the
sampled times marked), :func:`render_pair_video` and :class:`PanelRenderer` (the study's two-panel
stimuli, no timeline: the participants must not see the labels). Everything is written atomically.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import pandas as pd

from .errors import ConvSynthError, MissingFileError
from .utils import atomic_path

log = logging.getLogger(__name__)

BODY_RGB = ((52, 92, 168), (214, 122, 40), (63, 143, 79), (138, 79, 160))   # character 0, 1, 2, 3
SKIN_RGB = (233, 196, 160)
NOSE_RGB = (200, 150, 115)
BACKGROUND_TOP, BACKGROUND_FLOOR = (236, 238, 242), (205, 203, 198)
LABEL_RGB = {"PC": (79, 111, 168), "LR": (61, 154, 91), "HP": (217, 164, 65), "PH": (217, 164, 65), "G": (138, 79, 160)}
LABEL_NAMES = {"PC": "phonemic clause", "LR": "listener response", "HP": "hesitation pause",
               "PH": "partner's hesitation", "G": "gesture"}
OTHER_LABEL_RGB = (150, 150, 150)
TICK_RGB = (214, 39, 40)            # synthetic transitions: timeline ticks only, never a body
CURSOR_RGB = (25, 25, 25)
PAGE_RGB = (255, 255, 255)
ROW_RGB = (236, 237, 241)
TEXT_RGB = (40, 40, 40)
MUTED_RGB = (110, 110, 110)

# sizes as fractions of a body's stature
TORSO_RADIUS, LIMB_RADIUS, HEAD_RADIUS, HAND_RADIUS = 0.036, 0.022, 0.068, 0.03
HEAD_LIFT = 0.05          # the head disc's centre above the head joint


# ------------------------------------------------------------------------------------------ bodies
@dataclass(frozen=True)
class DrawnBody:
    """One character to draw. positions: (frames, joints, 3) world positions (Y up); parents:
    (joints,) parent index (-1 root, -2 not drawn); head, hands: joint indices (None / empty where
    the rig has none); torso: joints on the root-to-head chain (their bones are drawn thicker);
    shoulders: (left, right) joints (the facing direction, drawn as a nose; empty: no nose);
    size: the stature every radius is a fraction of (None: from the bones, :func:`stature`);
    color: index into BODY_RGB (None: the body's place in its panel)."""

    positions: np.ndarray
    parents: tuple[int, ...]
    head: int | None = None
    hands: tuple[int, ...] = ()
    torso: frozenset = frozenset()
    shoulders: tuple[int, ...] = ()
    name: str = ""
    size: float | None = None
    color: int | None = None

    @property
    def num_frames(self) -> int:
        return int(self.positions.shape[0])


def stature(body: DrawnBody) -> float:
    """Bone lengths (frame 0) along the tree from the head down to the lowest joint: a body's height
    whether it sits or stands, whatever lies above the hips (a static world root joint adds
    nothing). Falls back to the vertical extent."""
    if body.size is not None:
        return float(body.size)
    p = np.asarray(body.positions[0], np.float64)
    par = body.parents

    def chain(j):   # {joint: bone length from it up to j} along the path to the root
        out, n = {}, 0.0
        while j is not None and j >= 0:
            out[j] = n
            if par[j] < 0:
                break
            n += float(np.linalg.norm(p[j] - p[par[j]]))
            j = par[j]
        return out

    top = body.head if body.head is not None else int(np.argmax(p[:, 1]))
    ends = [j for j in range(len(par)) if par[j] >= 0]          # joints that end a drawn bone (not the root)
    low = min(ends, key=lambda j: p[j, 1]) if ends else 0
    up, down = chain(top), chain(low)
    common = [j for j in down if j in up]
    s = min((up[j] + down[j] for j in common), default=0.0)
    return s if s > 1e-9 else float(np.ptp(p[:, 1]) or 1.0)


def body_from_motion(motion, name: str = "", color: int | None = None) -> DrawnBody:
    """A :class:`DrawnBody` from a :class:`~convsynth_jax.skeleton.Motion` (forward kinematics and the rig's
    roles, :func:`convsynth_jax.rig.find_role`). Joints below a hand (fingers) are not drawn: the
    hand disc stands for them."""
    from .kinematics import forward_kinematics_np
    from .rig import find_role

    sk = motion.skeleton
    pos = np.asarray(forward_kinematics_np(motion), dtype=np.float32)
    if not np.all(np.isfinite(pos)):
        raise ConvSynthError(f"forward kinematics gives non-finite joint positions (body {name!r})")
    parents = tuple(int(p) for p in sk.parents)
    head = find_role(sk, "head")
    hands = tuple(j for j in (find_role(sk, "left_hand"), find_role(sk, "right_hand")) if j is not None)
    shoulders = tuple(j for j in (find_role(sk, "left_shoulder"), find_role(sk, "right_shoulder")) if j is not None)
    torso = set()
    j = head if head is not None else int(np.argmax(pos[0, :, 1]))
    while j >= 0:
        torso.add(j)
        j = parents[j]
    below_hand = sk.below(hands)
    kept = tuple(-2 if j in below_hand else p for j, p in enumerate(parents))
    b = DrawnBody(pos, kept, head, hands, frozenset(torso), shoulders if len(shoulders) == 2 else (), name, color=color)
    return replace(b, size=stature(b))


def frozen(body: DrawnBody, frame: int = 0) -> DrawnBody:
    """``body`` held at ``frame`` for its whole length (the study's attention checks)."""
    return replace(body, positions=np.repeat(body.positions[frame:frame + 1], body.num_frames, axis=0))


def _facing(body: DrawnBody, frame: int) -> np.ndarray | None:
    """The horizontal unit vector the body faces at ``frame`` (up x (right shoulder - left shoulder)),
    None without shoulders."""
    if len(body.shoulders) != 2:
        return None
    p = body.positions[frame]
    d = np.asarray(p[body.shoulders[1]] - p[body.shoulders[0]], np.float64)
    f = np.array([d[2], 0.0, -d[0]])          # (0, 1, 0) x d
    n = np.linalg.norm(f)
    return f / n if n > 1e-9 else None


# ------------------------------------------------------------------------------------------ camera
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


# ------------------------------------------------------------------------------------------ rasterizer
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


# ------------------------------------------------------------------------------------------ text
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


# ------------------------------------------------------------------------------------------ timeline
@dataclass(frozen=True)
class Timeline:
    """One row of the timeline: ``segments`` (columns kind, start, end; seconds from the first frame)
    drawn as coloured bars (the kind written inside where it fits); ``ticks``: times (seconds) of
    synthetic transitions, drawn as ticks under the bars; ``color``: the index of the body whose
    colour the row's name is marked with (None: unmarked)."""

    name: str
    segments: pd.DataFrame = field(default_factory=lambda: pd.DataFrame(columns=["kind", "start", "end"]))
    ticks: tuple = ()
    color: int | None = None


def _label_rgb(kind: str):
    return LABEL_RGB.get(kind, OTHER_LABEL_RGB)


@dataclass(frozen=True)
class StripLayout:
    """Where the timeline's parts lie in its image (pixels; rows from its top): the gutter of names
    ``[0, gutter)``, the drawn time axis ``[x0, x0 + area)`` at ``pps`` pixels per second (scrolled
    by ``offset(t)``), per row the bar ``(top, bottom)`` and tick band ``(top, bottom)``, the legend's
    rows, and each name's box (x0, y0, x1, y1)."""

    width: int
    height: int
    gutter: int
    x0: int
    area: int
    pps: float
    axis: tuple
    bars: tuple
    ticks: tuple
    legend: tuple
    names: tuple


class TimelineStrip:
    """The timeline under the panels (see the module docstring). ``view(t)``: the (height, width, 3)
    uint8 image at time ``t`` with its cursor; ``x_of(t, at)``: the column of time ``t`` in the image
    shown at time ``at``. Duration: seconds of motion shown; ``span_s``: the most seconds shown at
    once (None: all)."""

    ROW_BAR, ROW_TICK, ROW_GAP, AXIS_H, LEGEND_H, PAD = 16, 7, 5, 15, 16, 6

    def __init__(self, timelines, duration: float, width: int, span_s: float | None = 15.0, font_px: int = 11,
                 markers=()):
        self.timelines = [t for t in timelines if t is not None]
        self.duration = max(float(duration), 1e-6)
        self.font, self.small = _font(font_px), _font(max(font_px - 1, 6))
        width = int(width)
        names = [t.name for t in self.timelines]
        swatch = 12
        want = max([_text_width(n, self.font) for n in names] or [0]) + swatch + 2 * self.PAD
        gutter = int(min(want, 0.35 * width)) if names else self.PAD
        x0 = gutter + self.PAD
        area = max(width - x0 - self.PAD, 10)
        shown = self.duration if span_s is None else min(self.duration, float(span_s))
        pps = area / shown
        y = self.PAD
        axis = (y, y + self.AXIS_H)
        y = axis[1] + 2
        bars, ticks, boxes = [], [], []
        for t in self.timelines:
            bars.append((y, y + self.ROW_BAR))
            y += self.ROW_BAR
            ticks.append((y + 1, y + self.ROW_TICK))
            y += self.ROW_TICK + self.ROW_GAP
        present = {str(k) for t in self.timelines if len(t.segments) for k in t.segments["kind"].astype(str)}
        # the known labels in their order, then any other label drawn (e.g. a registered kind's, in grey)
        self.kinds = [k for k in LABEL_RGB if k in present] + sorted(present - set(LABEL_RGB))
        self.has_ticks = any(len(t.ticks) for t in self.timelines)
        legend_rows = self._legend_rows(width)
        legend = (y, y + self.LEGEND_H * len(legend_rows))
        height = legend[1] + self.PAD
        height += height % 2
        for t, (b0, _), (_, k1) in zip(self.timelines, bars, ticks):
            boxes.append((self.PAD, b0, gutter, k1))
        self.layout = StripLayout(width, height, gutter, x0, area, pps, axis, tuple(bars), tuple(ticks), legend,
                                  tuple(boxes))
        self._legend = legend_rows
        self.markers = tuple(float(m) for m in markers)
        self._static, self._strip = self._draw_static(), self._draw_strip()

    # -- layout helpers
    def _legend_rows(self, width: int) -> list:
        items = [(k, f"{k} {LABEL_NAMES.get(k, k)}") for k in self.kinds]
        if self.has_ticks:
            items.append(("tick", "synthetic transition"))
        rows, cur, x = [], [], self.PAD
        for it in items:
            w = 14 + _text_width(it[1], self.small) + 12
            if cur and x + w > width - self.PAD:
                rows.append(cur)
                cur, x = [], self.PAD
            cur.append(it)
            x += w
        if cur:
            rows.append(cur)
        return rows

    def offset(self, t: float) -> float:
        """Pixels of the strip scrolled out to the left at time ``t`` (0 while it all fits)."""
        L = self.layout
        total = self.duration * L.pps
        return float(np.clip(t * L.pps - 0.5 * L.area, 0.0, max(0.0, total - L.area)))

    def x_of(self, t: float, at: float | None = None) -> float:
        """The image column of time ``t`` when the strip shows time ``at`` (default: ``t``)."""
        L = self.layout
        return L.x0 + t * L.pps - self.offset(t if at is None else at)

    # -- drawing
    def _draw_static(self) -> np.ndarray:
        """The parts that never move: page, gutter with names and colour swatches, legend."""
        from PIL import Image, ImageDraw

        L = self.layout
        im = Image.new("RGB", (L.width, L.height), PAGE_RGB)
        d = ImageDraw.Draw(im)
        for t, (x0, y0, x1, _), (b0, b1) in zip(self.timelines, L.names, L.bars):
            tx = x0
            if t.color is not None:
                d.rectangle([x0, b0 + 3, x0 + 8, b1 - 4], fill=BODY_RGB[t.color % len(BODY_RGB)])
                tx = x0 + 12
            d.text((tx, (b0 + b1) / 2), _fit(t.name, self.font, x1 - tx), font=self.font, fill=TEXT_RGB, anchor="lm")
        y = L.legend[0]
        for row in self._legend:
            x = self.PAD
            for key, text in row:
                cy = y + self.LEGEND_H // 2
                if key == "tick":
                    d.rectangle([x + 4, cy - 5, x + 5, cy + 5], fill=TICK_RGB)
                else:
                    d.rectangle([x, cy - 4, x + 9, cy + 4], fill=_label_rgb(key))
                d.text((x + 14, cy), text, font=self.small, fill=MUTED_RGB, anchor="lm")
                x += 14 + _text_width(text, self.small) + 12
            y += self.LEGEND_H
        return np.asarray(im, np.uint8).copy()

    def _draw_strip(self) -> np.ndarray:
        """The whole duration at ``pps``: axis, bars, kind names, ticks (rows of the image, columns
        from time 0)."""
        from PIL import Image, ImageDraw

        L = self.layout
        w = int(np.ceil(self.duration * L.pps)) + 2
        im = Image.new("RGB", (w, L.height), PAGE_RGB)
        d = ImageDraw.Draw(im)
        for (b0, b1), (k0, k1), t in zip(L.bars, L.ticks, self.timelines):
            d.rectangle([0, b0, w - 1, b1 - 1], fill=ROW_RGB)
            for r in t.segments.itertuples(index=False):
                s, e = max(float(r.start), 0.0), min(float(r.end), self.duration)
                if e <= s:
                    continue
                xs, xe = s * L.pps, e * L.pps
                d.rectangle([int(round(xs)), b0, max(int(round(xe)) - 1, int(round(xs))), b1 - 1], fill=_label_rgb(str(r.kind)))
                label = str(r.kind)
                if _text_width(label, self.small) + 4 <= xe - xs:
                    d.text(((xs + xe) / 2, (b0 + b1) / 2), label, font=self.small, fill=(255, 255, 255), anchor="mm")
            for tick in t.ticks:
                if 0.0 <= tick <= self.duration:
                    x = int(round(float(tick) * L.pps))
                    d.rectangle([x, k0, x + 1, k1 - 1], fill=TICK_RGB)
        step = next((s for s in (0.5, 1, 2, 5, 10, 15, 30, 60, 120, 300, 600, 1800) if s * L.pps >= 48), 3600)
        a0, a1 = L.axis
        for k in range(int(self.duration / step) + 1):
            t = k * step
            x = int(round(t * L.pps))
            d.line([x, a1 - 4, x, a1 - 1], fill=MUTED_RGB)
            label = f"{t:g} s"
            tw = _text_width(label, self.small)
            d.text((min(max(x, tw / 2), w - tw / 2 - 1), a0 + 5), label, font=self.small, fill=MUTED_RGB, anchor="mm")
        for m in self.markers:
            x = int(round(m * L.pps))
            for yy in range(L.bars[0][0] if L.bars else a1, (L.ticks[-1][1] if L.ticks else a1), 3):
                d.point([(x, yy)], fill=(90, 90, 90))
        return np.asarray(im, np.uint8).copy()

    def view(self, t: float, cursor: bool = True) -> np.ndarray:
        """The timeline image at time ``t``: static parts, the strip's window, the cursor."""
        L = self.layout
        img = self._static.copy()
        off = int(round(self.offset(t)))
        part = self._strip[:L.legend[0], off:off + L.area]
        img[:L.legend[0], L.x0:L.x0 + part.shape[1]] = part
        if cursor and self.timelines:
            x = int(round(self.x_of(t)))
            if L.x0 <= x < L.x0 + L.area:
                img[L.axis[0]:L.ticks[-1][1], max(x - 1, 0):x + 1] = CURSOR_RGB
        return img


# ------------------------------------------------------------------------------------------ frames
@dataclass(frozen=True)
class Panel:
    """One view (e.g. "synthesized" or "ground truth") holding the bodies drawn together."""

    title: str
    bodies: tuple


class FrameRenderer:
    """Frames (H, W, 3) uint8 of ``panels`` side by side (one camera for all, fitted to every body),
    a header with the panels' titles and the clock, and the timeline underneath (see the module
    docstring). ``frame(f)``: the image at motion frame ``f``; ``layout``: where things lie."""

    HEADER = 22

    def __init__(self, panels, timelines, fps: float, panel_width: int = 480, panel_height: int = 360,
                 timeline_span_s: float | None = 15.0, yaw_deg: float = 35.0, pitch_deg: float = 12.0, clock: bool = True,
                 font_px: int = 11, markers=(), across=None):
        panels = list(panels)
        if not panels or not all(p.bodies for p in panels):
            raise ConvSynthError("nothing to render: every panel needs at least one body")
        self.panels, self.fps, self.clock = panels, float(fps), clock
        self.n = min(b.num_frames for p in panels for b in p.bodies)
        self.pw, self.ph = int(panel_width) + int(panel_width) % 2, int(panel_height) + int(panel_height) % 2
        self.renderer = PanelRenderer([p.bodies for p in panels], self.pw, self.ph, 1, yaw_deg, pitch_deg, across)
        self.width = len(panels) * self.pw + 2 * (len(panels) - 1)
        self.header = self.HEADER if (clock or any(p.title for p in panels)) else 0
        self.timeline = TimelineStrip(timelines, self.n / self.fps, self.width, timeline_span_s, font_px, markers) \
            if timelines else None
        self.height = self.header + self.ph + (self.timeline.layout.height if self.timeline else 0)
        self.height += self.height % 2
        self.font = _font(font_px + 1, bold=True)
        self.clock_font = _font(font_px)
        self._static = self._draw_static()

    def panel_box(self, i: int) -> tuple:
        """(col0, row0, col1, row1) of panel ``i`` in the frame."""
        x = i * (self.pw + 2)
        return x, self.header, x + self.pw, self.header + self.ph

    @property
    def timeline_top(self) -> int:
        return self.header + self.ph

    def _draw_static(self) -> np.ndarray:
        from PIL import Image, ImageDraw

        im = Image.new("RGB", (self.width, self.height), PAGE_RGB)
        d = ImageDraw.Draw(im)
        for i, p in enumerate(self.panels):
            x0, _, x1, _ = self.panel_box(i)
            if p.title:
                room = (x1 - x0) - (90 if (self.clock and i == len(self.panels) - 1) else 12)
                d.text((x0 + 6, self.header / 2), _fit(p.title.replace("\n", "; "), self.font, room), font=self.font,
                       fill=TEXT_RGB, anchor="lm")
            if i:
                d.rectangle([x0 - 2, self.header, x0 - 1, self.header + self.ph - 1], fill=(120, 120, 120))
        return np.asarray(im, np.uint8).copy()

    def _clock(self, img: np.ndarray, t: float) -> None:
        from PIL import Image, ImageDraw

        w, h = 84, self.header
        patch = Image.fromarray(img[:h, self.width - w:].copy())
        ImageDraw.Draw(patch).text((w - 6, h / 2), f"{t:6.1f} s", font=self.clock_font, fill=TEXT_RGB, anchor="rm")
        img[:h, self.width - w:] = np.asarray(patch)

    def frame(self, f: int) -> np.ndarray:
        f = int(min(max(f, 0), self.n - 1))
        img = self._static.copy()
        for i, p in enumerate(self.panels):
            x0, y0, x1, y1 = self.panel_box(i)
            img[y0:y1, x0:x1] = self.renderer.draw(p.bodies, f)
        t = f / self.fps
        if self.timeline is not None:
            tl = self.timeline.view(t)
            img[self.timeline_top:self.timeline_top + tl.shape[0]] = tl
        if self.clock and self.header:
            self._clock(img, t)
        return img

    def frames(self, step: int = 1):
        for f in range(0, self.n, max(1, int(step))):
            yield self.frame(f)


# ------------------------------------------------------------------------------------------ files
def ffmpeg_exe() -> str:
    """The ffmpeg binary that the ``imageio-ffmpeg`` package ships (a project dependency)."""
    try:
        import imageio_ffmpeg
    except ImportError as e:  # pragma: no cover - a dependency of the package
        raise ConvSynthError("video output needs the imageio-ffmpeg package (pip install imageio-ffmpeg)") from e
    return imageio_ffmpeg.get_ffmpeg_exe()


def write_mp4(path: Path, first, rest, fps: float, audio: str | Path | None = None, **writer_options) -> Path:
    """Write the RGB frames ``first`` and then ``rest`` to the MP4 ``path`` (atomically: a temporary file
    renamed into place), with the WAV ``audio`` muxed in as AAC when given. ``writer_options``: further
    keyword arguments of ``imageio_ffmpeg.write_frames`` (codec, pixel format, block size)."""
    import os

    import imageio_ffmpeg

    # imageio-ffmpeg starts ffmpeg with preexec_fn=os.setpgrp (to keep Ctrl-C from it), which makes
    # Python run the at-fork hooks: JAX's warns "os.fork() was called ... deadlock" on every video.
    # Without it ffmpeg starts without a fork hook in this process (and a Ctrl-C stops it too).
    os.environ.setdefault("IMAGEIO_FFMPEG_NO_PREVENT_SIGINT", "1")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path, suffix=".mp4") as tmp:
        w = imageio_ffmpeg.write_frames(str(tmp), (first.shape[1], first.shape[0]), fps=fps,
                                        audio_path=None if audio is None else str(audio),
                                        audio_codec=None if audio is None else "aac", ffmpeg_log_level="error",
                                        **writer_options)
        w.send(None)
        w.send(first)
        for img in rest:
            w.send(img)
        w.close()
    return path


def write_video(frames, fps: float, path: str | Path, audio: str | Path | None = None) -> Path:
    """Write ``frames`` (an iterable of uint8 (H, W, 3), even H and W) to ``path``: MP4, H.264 yuv420p
    with ``+faststart``, plus the WAV ``audio`` as AAC when given. Written atomically. Encoding
    settings are chosen for speed: x264 ``superfast`` and ffmpeg's ``fast`` AAC coder take 3.2-3.8 s
    of ffmpeg CPU for a minute of 640 x 484 at 10 fps against 5.2-5.3 s with ``veryfast`` and the
    default coder (docs/render.md); the files are larger, 2.2 MB per minute."""
    path = Path(path)
    gen = iter(frames)
    first = next(gen)
    if first.shape[0] % 2 or first.shape[1] % 2:
        raise ConvSynthError(f"H.264 frames need an even width and height, got {first.shape[1]} x {first.shape[0]}", path)
    return write_mp4(path, first, gen, fps, audio, macro_block_size=2, codec="libx264", pix_fmt_out="yuv420p",
                     output_params=["-preset", "superfast", *(["-aac_coder", "fast"] if audio is not None else []),
                                    "-movflags", "+faststart"])


def probe_streams(path: str | Path) -> dict:
    """{"video": n, "audio": n, "duration": seconds or None}: the streams ffmpeg finds in a media file
    (read from ``ffmpeg -i``'s report, with the ffmpeg binary of ``imageio-ffmpeg``)."""
    import re
    import subprocess

    p = Path(path)
    if not p.is_file():
        raise MissingFileError("no such media file", p)
    err = subprocess.run([ffmpeg_exe(), "-hide_banner", "-i", str(p)], capture_output=True, text=True).stderr
    d = re.search(r"Duration: (\d+):(\d+):([\d.]+)", err)
    dur = None if d is None else 3600 * int(d.group(1)) + 60 * int(d.group(2)) + float(d.group(3))
    return {"video": len(re.findall(r"Stream #\S+.*: Video:", err)), "audio": len(re.findall(r"Stream #\S+.*: Audio:", err)),
            "duration": dur}


def _step(fps: float, render_fps: float) -> int:
    if not render_fps or render_fps <= 0:
        raise ConvSynthError(f"the frames drawn per second must be positive, got {render_fps}")
    return max(1, int(round(float(fps) / float(render_fps))))


def render_video(panels, timelines, fps: float, path: str | Path, audio: str | Path | None = None,
                 render_fps: float = 10.0, panel_width: int = 480, panel_height: int = 360,
                 timeline_span_s: float | None = 15.0, clock: bool = True, yaw_deg: float = 35.0,
                 pitch_deg: float = 12.0, across=None) -> Path:
    """An H.264 MP4 of ``panels`` over the ``timelines`` (every ``round(fps / render_fps)``-th motion
    frame, :class:`FrameRenderer`), with the WAV ``audio`` (if given) muxed in as AAC from frame 0.
    ``across``: see :func:`three_quarter_camera`."""
    r = FrameRenderer(panels, timelines, fps, panel_width, panel_height, timeline_span_s, yaw_deg, pitch_deg, clock,
                      across=across)
    step = _step(fps, render_fps)
    return write_video(r.frames(step), fps / step, path, audio)


def render_animation(panels, timelines, fps: float, path: str | Path, render_fps: float = 10.0,
                     panel_width: int = 320, panel_height: int = 260, timeline_span_s: float | None = None,
                     clock: bool = True) -> Path:
    """Animate ``panels`` over ``timelines`` to ``path``: ``.gif`` (frames mapped onto one palette,
    written with Pillow) or ``.mp4`` (:func:`render_video`, no audio). Every
    ``round(fps / render_fps)``-th frame is drawn."""
    path = Path(path)
    step = _step(fps, render_fps)
    if path.suffix.lower() == ".mp4":
        return render_video(panels, timelines, fps, path, None, render_fps, panel_width, panel_height, timeline_span_s, clock)
    if path.suffix.lower() != ".gif":
        raise ConvSynthError(f"an animation is a .gif or an .mp4, not {path.suffix or 'a file without suffix'}", path)
    from PIL import Image

    r = FrameRenderer(panels, timelines, fps, panel_width, panel_height, timeline_span_s, clock=clock)
    palette, images = None, []
    for img in r.frames(step):
        if palette is None:   # one palette: the first frame plus every body, label and tick colour
            swatch = np.array([*BODY_RGB, SKIN_RGB, NOSE_RGB, *LABEL_RGB.values(), TICK_RGB, CURSOR_RGB], np.uint8)
            strip = np.zeros((8, img.shape[1], 3), np.uint8) + 255
            cells = np.repeat(swatch, 8, axis=0)[: img.shape[1]]
            strip[:, :len(cells)] = cells[None]
            palette = Image.fromarray(np.concatenate([img, strip])).quantize(colors=128, method=Image.Quantize.MEDIANCUT)
        images.append(Image.fromarray(img).quantize(palette=palette, dither=Image.Dither.NONE))
    with atomic_path(path) as tmp:
        images[0].save(tmp, format="GIF", save_all=True, append_images=images[1:], loop=0,
                       duration=int(round(1000 * step / fps)))
    return path


def contact_sheet(panels, timelines, fps: float, path: str | Path, num: int = 6, cell_width: int = 220,
                  cell_height: int = 200) -> Path:
    """A PNG grid: one row per panel (its title on the left), ``num`` evenly spaced frames per row
    (their times above), one camera for all; under it the whole timeline with the sampled times
    marked (dotted). Written atomically."""
    from PIL import Image, ImageDraw

    panels = list(panels)
    if not panels or not all(p.bodies for p in panels):
        raise ConvSynthError("nothing to render: every panel needs at least one body")
    n = min(b.num_frames for p in panels for b in p.bodies)
    frames = np.unique(np.linspace(0, n - 1, max(1, int(num))).round().astype(int))
    cw, ch = int(cell_width), int(cell_height)
    font, bold = _font(11), _font(12, bold=True)
    title_w = min(max(_text_width(p.title.replace("\n", "; "), bold) for p in panels) + 16, 180)
    top = 20
    width = title_w + len(frames) * (cw + 4)
    renderer = PanelRenderer([p.bodies for p in panels], cw, ch)
    strip = TimelineStrip(timelines, n / fps, width, None, markers=frames / fps) if timelines else None
    height = top + len(panels) * (ch + 4) + (strip.layout.height if strip else 0)
    im = Image.new("RGB", (width, height), PAGE_RGB)
    d = ImageDraw.Draw(im)
    for c, f in enumerate(frames):
        d.text((title_w + c * (cw + 4) + cw / 2, top / 2), f"{f / fps:.1f} s", font=font, fill=TEXT_RGB, anchor="mm")
    for i, p in enumerate(panels):
        y = top + i * (ch + 4)
        d.text((6, y + ch / 2), _fit(p.title.replace("\n", "; "), bold, title_w - 10), font=bold, fill=TEXT_RGB, anchor="lm")
        for c, f in enumerate(frames):
            im.paste(Image.fromarray(renderer.draw(p.bodies, int(f))), (title_w + c * (cw + 4), y))
    if strip is not None:
        im.paste(Image.fromarray(strip.view(0.0, cursor=False)), (0, top + len(panels) * (ch + 4)))
    path = Path(path)
    with atomic_path(path) as tmp:
        im.save(tmp, format="PNG")
    return path


# ------------------------------------------------------------------------------------------ study stimuli
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
    for both panels, fitted to all bodies), every ``step``-th frame."""
    if not left or not right:
        raise ConvSynthError("a study video needs bodies in both panels")
    r = PanelRenderer([left, right], width, height, step, yaw_deg, pitch_deg)
    yield from join_panels(r.frames(left), r.frames(right))


def render_pair_video(left, right, fps: float, path: str | Path, audio: str | Path | None = None, width: int = 320,
                      height: int = 360, render_fps: float = 15.0, yaw_deg: float = 35.0, pitch_deg: float = 12.0) -> Path:
    """Write ``path`` (MP4, H.264 yuv420p + AAC when ``audio`` is a WAV), the ``left`` and ``right``
    bodies (motion at ``fps``) side by side, drawn at about ``render_fps``. Written atomically."""
    if width % 2 or height % 2:
        raise ConvSynthError(f"study video panels need an even width and height, got {width} x {height}")
    step = _step(fps, render_fps)
    return write_video(side_by_side_frames(left, right, width, height, step, yaw_deg, pitch_deg), fps / step, path, audio)
