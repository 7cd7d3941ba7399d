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

**Modules, by job:** ``style`` (colours, sizes), ``bodies`` (:class:`DrawnBody`, stature, facing),
``camera``, ``raster`` (painter's order, :func:`rasterize`, :class:`PanelRenderer`), ``text`` (fonts),
``timeline`` (:class:`TimelineStrip`), ``frames`` (:class:`FrameRenderer`), ``video`` (ffmpeg, MP4, GIF,
contact sheet) and ``study`` (the study's two-panel stimuli). Every public name is importable from
``convsynth_jax.render``.
"""
from __future__ import annotations

from .style import (BACKGROUND_FLOOR, BACKGROUND_TOP, BODY_RGB, CURSOR_RGB, HAND_RADIUS, HEAD_LIFT, HEAD_RADIUS,
                    LABEL_NAMES, LABEL_RGB, LIMB_RADIUS, MUTED_RGB, NOSE_RGB, OTHER_LABEL_RGB, PAGE_RGB, ROW_RGB,
                    SKIN_RGB, TEXT_RGB, TICK_RGB, TORSO_RADIUS)
from .bodies import body_from_motion, DrawnBody, frozen, stature
from .camera import Camera, three_quarter_camera
from .raster import Backdrop, draw_panel, painter_order, PanelRenderer, rasterize, SUPERSAMPLE
from .timeline import StripLayout, Timeline, TimelineStrip
from .frames import FrameRenderer, Panel
from .video import contact_sheet, ffmpeg_exe, probe_streams, render_animation, render_video, write_mp4, write_video
from .study import join_panels, render_pair_video, side_by_side_frames
from .camera import _project  # noqa: F401  (the rendering tests project and draw through these)
from .raster import _background  # noqa: F401

__all__ = ["Backdrop", "BACKGROUND_FLOOR", "BACKGROUND_TOP", "body_from_motion", "BODY_RGB", "Camera",
           "contact_sheet", "CURSOR_RGB", "draw_panel", "DrawnBody", "ffmpeg_exe", "FrameRenderer", "frozen",
           "HAND_RADIUS", "HEAD_LIFT", "HEAD_RADIUS", "join_panels", "LABEL_NAMES", "LABEL_RGB", "LIMB_RADIUS",
           "MUTED_RGB", "NOSE_RGB", "OTHER_LABEL_RGB", "PAGE_RGB", "painter_order", "Panel", "PanelRenderer",
           "probe_streams", "rasterize", "render_animation", "render_pair_video", "render_video", "ROW_RGB",
           "side_by_side_frames", "SKIN_RGB", "stature", "StripLayout", "SUPERSAMPLE", "TEXT_RGB",
           "three_quarter_camera", "TICK_RGB", "Timeline", "TimelineStrip", "TORSO_RADIUS", "write_mp4",
           "write_video"]
