"""The one renderer (convsynth_jax.render): its rasterizer against a per-pixel reference, the
three-quarter camera, frames checked against where things must be (each body in its place and its
colour, the timeline's names inside the image, labels and transition ticks at their times, the
scrolling timeline), the files (GIF, MP4, contact sheet) and ``task=render``."""
import json
import shutil

import numpy as np
import pandas as pd
import pytest
from conftest import TEST_DATA
from PIL import Image

from convsynth_jax import render as R
from convsynth_jax.config import compose, run_task
from convsynth_jax.errors import ConvSynthError, MissingFileError
from convsynth_jax.io import load_bvh
from convsynth_jax.testing.render_reference import rasterize_reference

BVH = TEST_DATA / "dataset-2_raise-up-right-hand_normal_016.bvh"
BVH2 = TEST_DATA / "dataset-2_raise-up-both-hands_normal_028.bvh"


# ------------------------------------------------------------------------------------------ rasterizer
def _coverage(img, backdrop, rgb):
    """Per pixel, the fraction of the way from the backdrop to ``rgb`` (along the channel that differs most)."""
    den = np.asarray(rgb, float) - backdrop
    k = np.argmax(np.abs(den), -1)
    i, j = np.indices(k.shape)
    return (img - backdrop)[i, j, k] / den[i, j, k]


def _random_shapes(rng, n, w, h):
    out = []
    for _ in range(n):
        p0 = rng.uniform(-4, max(w, h) + 4, 2)
        p1 = p0 + rng.uniform(-25, 25, 2) * (rng.uniform() > 0.25)      # a quarter are discs
        out.append((tuple(p0), tuple(p1), float(rng.uniform(0.6, 7.0)), tuple(rng.uniform(0, 255, 3).round())))
    return out


@pytest.mark.parametrize("seed", range(2))
def test_rasterize_agrees_with_the_per_pixel_reference(seed):
    """Each shape alone: every pixel's coverage lies between the reference's for the radius 0.7 px
    smaller and 0.7 px larger (Pillow draws at SUPERSAMPLE x SUPERSAMPLE samples with coordinates and
    widths rounded to whole samples, half a pixel at 2, and its wide lines' edges are off by up to about
    one more sample); and the mean error along the edges is under half a sample."""
    rng = np.random.default_rng(seed)
    w, h = 44, 36
    bg = R._background(w, h, 26)
    samples, down = np.asarray(bg).astype(float), np.asarray(bg.reduce(R.SUPERSAMPLE)).astype(float)
    errors = []
    for p0, p1, r, rgb in _random_shapes(rng, 10, w, h):
        fast = _coverage(R.rasterize([(p0, p1, r, rgb)], bg).astype(float), down, rgb)
        exact = _coverage(rasterize_reference([(p0, p1, r, rgb)], samples, R.SUPERSAMPLE), down, rgb)
        lo = _coverage(rasterize_reference([(p0, p1, max(r - 0.7, 0.0), rgb)], samples, R.SUPERSAMPLE), down, rgb)
        hi = _coverage(rasterize_reference([(p0, p1, r + 0.7, rgb)], samples, R.SUPERSAMPLE), down, rgb)
        assert (fast >= lo - 0.02).all() and (fast <= hi + 0.02).all(), (p0, p1, r)
        edge = (exact > 0) | (fast > 0)
        if edge.any():
            errors.append(np.abs(fast - exact)[edge].mean())
    assert np.mean(errors) < 0.125, errors


def test_later_shapes_cover_earlier_ones():
    bg = R._background(40, 30, 30)
    red, blue = (220.0, 30.0, 30.0), (30.0, 30.0, 220.0)
    img = R.rasterize([((5.0, 15.0), (35.0, 15.0), 6.0, red), ((20.0, 15.0), (20.0, 15.0), 5.0, blue)], bg)
    ref = rasterize_reference([((5.0, 15.0), (35.0, 15.0), 6.0, red), ((20.0, 15.0), (20.0, 15.0), 5.0, blue)],
                              np.asarray(bg).astype(float), R.SUPERSAMPLE)
    assert tuple(img[15, 20]) == (30, 30, 220) and tuple(img[15, 8]) == (220, 30, 30)
    inner = np.zeros(img.shape[:2], bool)
    inner[12:19, 18:23] = inner[13:18, 17:24] = True   # well inside the disc: the reference's colour exactly
    np.testing.assert_allclose(img[inner], ref[inner], atol=0.5)


# ------------------------------------------------------------------------------------------ bodies, camera
def _seated(x: float, facing: float, frames: int = 8, phase: float = 0.0, lift: float = 0.0) -> R.DrawnBody:
    """A seated body at ``x`` on the X axis facing ``facing`` (+1: +X, -1: -X), 1.6 units tall,
    waving its right hand. Joints: hips, chest, head, shoulders (l, r), hands (l, r), knee, foot."""
    f = float(facing)
    base = np.array([[0, 0.5, 0], [0, 1.0, 0], [0, 1.25, 0], [0, 1.0, -0.2 * f], [0, 1.0, 0.2 * f],
                     [0.3 * f, 0.7, -0.2 * f], [0.3 * f, 0.7, 0.2 * f], [0.45 * f, 0.5, 0], [0.45 * f, 0.0, 0]])
    pos = np.repeat(base[None], frames, axis=0).astype(np.float32)
    t = np.arange(frames)
    pos[:, 6, 1] += 0.25 * np.sin(0.8 * t + phase) + lift
    pos[..., 0] += x
    return R.DrawnBody(pos, (-1, 0, 1, 1, 1, 3, 4, 0, 7), head=2, hands=(5, 6), torso=frozenset({0, 1, 2}), shoulders=(3, 4))


def test_stature_is_the_same_seated_or_standing():
    seated = _seated(0.0, 1.0)
    standing_pos = seated.positions.copy()
    standing_pos[:, 7] = standing_pos[:, 0] + (0, -0.45, 0)          # the thigh hangs down
    standing_pos[:, 8] = standing_pos[:, 7] + (0, -0.5, 0)
    standing = R.DrawnBody(standing_pos, seated.parents, seated.head, seated.hands, seated.torso, seated.shoulders)
    assert R.stature(seated) == pytest.approx(R.stature(standing), rel=1e-6)
    assert R.stature(seated) == pytest.approx(0.75 + 0.45 + 0.5, rel=1e-6)
    # a static world root far from the hips on the ground (bandai2's joint_Root) adds nothing: the
    # walk-and-talk demo's characters were drawn with heads of different sizes
    world = np.concatenate([np.zeros_like(seated.positions[:, :1]) + np.float32([3.0, 0.0, -2.0]), seated.positions], axis=1)
    rooted = R.DrawnBody(world, (-1, *[q + 1 if q >= 0 else 0 for q in seated.parents]), 3, (6, 7), frozenset({1, 2, 3}), (4, 5))
    assert R.stature(rooted) == pytest.approx(R.stature(seated), rel=1e-6)


def test_three_quarter_camera_turns_the_side_view_and_fits_the_panel():
    bodies = [_seated(-0.6, 1.0), _seated(0.6, -1.0)]
    side = R.three_quarter_camera(bodies, 100, 120, yaw_deg=0.0, pitch_deg=0.0)
    np.testing.assert_allclose(side.right, [1, 0, 0], atol=1e-12)                       # the first on the left
    np.testing.assert_allclose(np.cross(side.right, side.up), -side.view, atol=1e-12)   # not mirrored
    swapped = R.three_quarter_camera(bodies[::-1], 100, 120, yaw_deg=0.0, pitch_deg=0.0)
    np.testing.assert_allclose(swapped.right, [-1, 0, 0], atol=1e-12)
    tq = R.three_quarter_camera(bodies, 100, 120)
    assert abs(tq.view @ np.array([1.0, 0, 0])) > 0.5 and tq.view[1] < 0    # turned towards the characters, looking down
    for b in bodies:
        col, row, _ = R._project(tq, b.positions.reshape(-1, 3), 100, 120)
        assert col.min() >= 0 and col.max() <= 100 and row.min() >= 0 and row.max() <= 120
    # one body is seen from the front: it faces +X, so the camera looks along -X
    one = R.three_quarter_camera([_seated(0.0, 1.0)], 100, 120, yaw_deg=0.0, pitch_deg=0.0)
    np.testing.assert_allclose(one.view, [-1, 0, 0], atol=1e-12)
    # a given direction wins (the walk-and-talk demo: X across the pair however they drift)
    drift = [_seated(-0.6, 1.0), R.DrawnBody(_seated(0.6, -1.0).positions + np.float32([0, 0, 3.0]), bodies[1].parents)]
    np.testing.assert_allclose(R.three_quarter_camera(drift, 100, 120, 0.0, 0.0, across=(1, 0, 0)).right, [1, 0, 0])
    with pytest.raises(ConvSynthError, match="horizontal"):
        R.three_quarter_camera(bodies, 100, 120, across=(0, 1, 0))


def test_frames_are_even_sized_and_a_frozen_body_does_not_move():
    bodies = [_seated(-0.6, 1.0, 6), _seated(0.6, -1.0, 6, 1.0)]
    still = [R.frozen(b) for b in bodies]
    frames = list(R.side_by_side_frames(bodies, still, 40, 48))
    assert len(frames) == 6 and frames[0].shape == (48, 82, 3) and frames[0].dtype == np.uint8
    right = [f[:, 42:] for f in frames]
    left = [f[:, :40] for f in frames]
    assert all((r == right[0]).all() for r in right)
    assert any((x != left[0]).any() for x in left)
    with pytest.raises(ConvSynthError, match="even"):
        R.render_pair_video(bodies, still, 30.0, "x.mp4", width=41, height=48)


# ------------------------------------------------------------------------------------------ frames
def _is_body(img, k):
    """Pixels in the hue of body ``k`` (blue; orange), at any of its depth shades."""
    x = img.astype(int)
    r, g, b = x[..., 0], x[..., 1], x[..., 2]
    if k == 0:
        return (b > r + 60) & (b > g + 30)
    return (r > b + 90) & (g > b + 35) & (r > g + 40)


def _is_tick(img):
    x = img.astype(int)
    return (np.abs(x - R.TICK_RGB).sum(-1) < 40)


def _scene(frames=300, span=15.0, names=("A (female)", "B (male)")):
    bodies = (_seated(-0.6, 1.0, frames), _seated(0.6, -1.0, frames, 1.5))
    segs = [pd.DataFrame({"kind": ["PC", "HP", "PC"], "start": [0.5, 3.0, 4.0], "end": [2.5, 3.6, 6.0]}),
            pd.DataFrame({"kind": ["LR"], "start": [2.0], "end": [2.8]})]
    ticks = [(1.0, 4.5), (2.2,)]
    lines = [R.Timeline(n, s, t, k) for k, (n, s, t) in enumerate(zip(names, segs, ticks))]
    return R.FrameRenderer([R.Panel("conversation", bodies)], lines, 30.0, 240, 160, span)


def test_each_body_is_drawn_in_its_place_in_its_own_colour_at_every_time():
    """Body 0 left of body 1 (facing each other), each in its colour; no body pixel in the transition
    colour, also at the frames of a transition (bodies used to turn red there)."""
    r = _scene()
    x0, y0, x1, y1 = r.panel_box(0)
    for f in (0, 30, 66, 135):                 # 30 and 135: transitions of A; 66: of B
        img = r.frame(f)
        assert img.shape == (r.height, r.width, 3) and r.height % 2 == 0 and r.width % 2 == 0
        panel = img[y0:y1, x0:x1]
        a, b = _is_body(panel, 0), _is_body(panel, 1)
        assert a.sum() > 300 and b.sum() > 300
        cols_a, cols_b = np.nonzero(a)[1], np.nonzero(b)[1]
        assert np.percentile(cols_a, 95) < np.percentile(cols_b, 5)          # A on the left, B on the right
        assert not _is_tick(panel).any()
        assert _is_tick(img[r.timeline_top:]).any()                          # the ticks are on the timeline


def test_the_timeline_names_are_inside_the_image_and_long_ones_are_shortened():
    r = _scene(names=("A (female)", "B (a character with a very long name that cannot fit the gutter at all)"))
    L = r.timeline.layout
    img = r.frame(0)
    dark = img.astype(int).sum(-1) < 300
    assert not dark[:, :3].any() and not dark[:, -3:].any()
    for (bx0, by0, bx1, by1) in L.names:
        assert 0 < bx0 < bx1 <= L.gutter < r.width and 0 <= by0 < by1 <= L.height
        assert dark[r.timeline_top + by0:r.timeline_top + by1, bx0:bx1].sum() > 20      # the name is written there
    assert L.gutter <= 0.35 * r.width + 1                                              # the long name is cut, not the image
    short = _scene()
    assert short.timeline.layout.gutter < L.gutter


def test_labels_and_ticks_are_drawn_at_their_times():
    r = _scene()
    L, top = r.timeline.layout, r.timeline_top
    img = r.frame(0)
    for k, (s, e, kind) in ((0, (0.5, 2.5, "PC")), (0, (3.0, 3.6, "HP")), (1, (2.0, 2.8, "LR"))):
        x = int(round(r.timeline.x_of((s + e) / 2, 0.0)))
        (b0, b1) = L.bars[k]
        column = img[top + b0 + 2:top + b1 - 2, x].astype(int)
        assert (np.abs(column - R.LABEL_RGB[kind]).sum(-1) < 12).mean() > 0.4, (kind, column[:3])
    for k, t in ((0, 1.0), (0, 4.5), (1, 2.2)):
        x = r.timeline.x_of(t, 0.0)
        k0, k1 = L.ticks[k]
        band = _is_tick(img[top + k0:top + k1])
        hit = np.nonzero(band.any(0))[0]
        assert len(hit) and np.abs(hit - x).min() <= 1.5, (t, x, hit)
        (b0, b1) = L.bars[k]
        assert not _is_tick(img[top + b0:top + b1]).any()                      # ticks under the bars, not over them
    # the kinds shown are named in the legend; the cursor is at the frame's time
    assert r.timeline.kinds == ["PC", "LR", "HP"] and r.timeline.has_ticks
    img = r.frame(90)
    x = int(round(r.timeline.x_of(3.0)))
    assert (img[top + L.axis[0] + 2:top + L.ticks[-1][1] - 2, x].astype(int).sum(-1) < 150).all()


def test_a_long_timeline_scrolls_around_the_cursor():
    r = _scene(frames=1800, span=10.0)        # 60 s shown 10 s at a time
    tl = r.timeline
    L = tl.layout
    assert L.pps == pytest.approx(L.area / 10.0)
    assert tl.x_of(0.0) == pytest.approx(L.x0) and tl.offset(2.0) == 0.0            # the start: the cursor moves
    assert tl.x_of(30.0) == pytest.approx(L.x0 + L.area / 2)                      # the middle: the strip moves
    assert tl.x_of(31.0, 30.0) == pytest.approx(L.x0 + L.area / 2 + L.pps)
    assert tl.x_of(60.0) == pytest.approx(L.x0 + L.area, abs=1e-6)                # the end: the cursor moves again
    a, b = r.frame(300), r.frame(900)
    assert not np.array_equal(a[r.timeline_top:], b[r.timeline_top:])


# ------------------------------------------------------------------------------------------ files
def test_render_fixture_to_gif_mp4_and_contact_sheet(tmp_path):
    m, m2 = load_bvh(BVH), load_bvh(BVH2, fps=load_bvh(BVH).fps)
    a, b = R.body_from_motion(m, "a"), R.body_from_motion(m2, "b")
    assert a.head is not None and len(a.hands) == 2 and len(a.shoulders) == 2
    segs = pd.DataFrame({"kind": ["PC", "LR"], "start": [0.1, 0.8], "end": [0.6, 1.2]})
    panels = [R.Panel("synthesized", (a,)), R.Panel("ground truth", (b,))]
    lines = [R.Timeline("a", segs, (10 / m.fps,), 0)]
    n = min(m.num_frames, m2.num_frames)
    gif = R.render_animation(panels, lines, m.fps, tmp_path / "x.gif", render_fps=10)
    with Image.open(gif) as im:
        assert im.format == "GIF" and im.n_frames == len(range(0, n, 3))     # 30 fps drawn at 10 fps
    mp4 = R.render_animation(panels, lines, m.fps, tmp_path / "x.mp4", render_fps=10)
    assert R.probe_streams(mp4)["video"] == 1
    png = R.contact_sheet(panels, lines, m.fps, tmp_path / "x.png", num=4)
    with Image.open(png) as im:
        px = np.asarray(im.convert("RGB"))
    # one row per panel, one 220 x 200 cell per sampled frame (4 pitches of 224 at the right, rows of
    # 204 under a 20-pixel header): each panel's body is drawn in every cell of its row
    assert px.shape[0] > 20 + 2 * 204
    for row in range(2):
        for cell in range(4):
            x0, y0 = px.shape[1] - (4 - cell) * 224, 20 + row * 204
            assert _is_body(px[y0:y0 + 200, x0:x0 + 220], 0).sum() > 50, (row, cell)
    assert (np.abs(px.astype(int) - R.LABEL_RGB["PC"]).sum(-1) < 6).any()    # the PC label
    assert _is_tick(px).any()                                                # the transition at frame 10
    with pytest.raises(ConvSynthError, match="gif or an .mp4"):
        R.render_animation(panels, lines, m.fps, tmp_path / "x.avi")


def _cfg(*o):
    return compose(["task=render", "progress=false", "jax_cache.dir=null", *o])


def test_render_task_on_a_file_and_a_synthesize_folder(tmp_path):
    s = run_task(_cfg(f"path={BVH}"), tmp_path / "one")
    assert (tmp_path / "one" / "render.gif").is_file() and (tmp_path / "one" / "contact_sheet.png").is_file()
    assert s["frames"][0] == 0 and s["frames"][1] == load_bvh(BVH).num_frames
    # a task=synthesize folder: <character>.bvh + report.json with the transitions and the labels
    d = tmp_path / "synth"
    d.mkdir()
    shutil.copy(BVH, d / "female.bvh")
    shutil.copy(BVH2, d / "male.bvh")
    (d / "report.json").write_text(json.dumps({
        "characters": {"female": {"transitions": [{"frame": 5}, {"frame": 20}]}, "male": {"success": False}},
        "segments": {"female": [{"kind": "PC", "start": 0.2, "end": 0.7}], "male": [{"kind": "LR", "start": 0.4, "end": 0.9}]}}))
    s = run_task(_cfg(f"path={d}", "task.duration=1.0", "task.format=mp4"), tmp_path / "two")
    assert s["transitions"] == {"female": [5, 20]}
    assert s["frames"] == [0, 30] and s["animation"] == "render.mp4"
    assert R.probe_streams(tmp_path / "two" / "render.mp4")["video"] == 1
    with Image.open(tmp_path / "two" / "contact_sheet.png") as im:
        px = np.asarray(im.convert("RGB"))
    assert (np.abs(px.astype(int) - R.LABEL_RGB["LR"]).sum(-1) < 6).any() and _is_tick(px).any()
    (d / "report.json").write_text("{not json")
    with pytest.raises(ConvSynthError, match="report.json"):
        run_task(_cfg(f"path={d}"), tmp_path / "three")


def test_render_bad_input_names_the_path(tmp_path):
    with pytest.raises(MissingFileError, match="no such BVH file or folder"):
        run_task(_cfg(f"path={tmp_path / 'missing.bvh'}"), tmp_path / "o1")
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "notes.txt").write_text("x")
    with pytest.raises(MissingFileError, match="holds no .bvh files") as e:
        run_task(_cfg(f"path={tmp_path / 'empty'}"), tmp_path / "o2")
    assert str(tmp_path / "empty") in str(e.value)
    with pytest.raises(ConvSynthError, match="needs path="):
        run_task(_cfg(), tmp_path / "o3")
    with pytest.raises(ConvSynthError, match="outside the motion"):
        run_task(_cfg(f"path={BVH}", "task.start=100"), tmp_path / "o4")
    with pytest.raises(ConvSynthError, match="task.format"):
        run_task(_cfg(f"path={BVH}", "task.format=avi"), tmp_path / "o5")


def test_the_legend_names_every_label_drawn():
    """A label the renderer has no colour for (a registered kind's) is drawn grey and still named in
    the legend, after the known ones in their order."""
    segs = pd.DataFrame({"kind": ["LG", "LR", "PC"], "start": [0.1, 0.8, 1.5], "end": [0.6, 1.2, 2.0]})
    strip = R.TimelineStrip([R.Timeline("a", segs)], 3.0, 640)
    assert strip.kinds == ["PC", "LR", "LG"]
    assert any(k == "LG" for row in strip._legend for k, _ in row)
