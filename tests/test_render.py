"""Stick-figure rendering (convsynth_jax.render) and ``task=render``."""
import json
import shutil

import numpy as np
import pandas as pd
import pytest
from conftest import TEST_DATA
from PIL import Image

from convsynth_jax.config import compose, run_task
from convsynth_jax.errors import ConvSynthError, MissingFileError
from convsynth_jax.io import load_bvh
from convsynth_jax.render import Panel, Timeline, contact_sheet, render_animation, track_from_motion

BVH = TEST_DATA / "dataset-2_raise-up-right-hand_normal_016.bvh"
BVH2 = TEST_DATA / "dataset-2_raise-up-both-hands_normal_028.bvh"


def test_render_fixture_to_gif_and_png(tmp_path):
    m = load_bvh(BVH)
    a, b = track_from_motion(m, "a", transitions=[10]), track_from_motion(load_bvh(BVH2, fps=m.fps), "b")
    segs = pd.DataFrame({"kind": ["PC", "LR"], "start": [0.1, 0.8], "end": [0.6, 1.2]})
    panels = [Panel("synthesized", (a,)), Panel("ground truth", (b,))]
    gif = render_animation(panels, [Timeline("a", segs)], m.fps, tmp_path / "x.gif", render_fps=10)
    n = min(m.num_frames, load_bvh(BVH2, fps=m.fps).num_frames)
    with Image.open(gif) as im:
        assert im.format == "GIF"
        assert im.n_frames == len(range(0, n, 3))  # 30 fps drawn at 10 fps
    png = contact_sheet(panels, [Timeline("a", segs)], m.fps, tmp_path / "x.png", num=4)
    with Image.open(png) as im:
        assert im.format == "PNG"
        px = np.asarray(im.convert("RGB"))
    # the transition at frame 10 is drawn red in no sheet frame (0, 16, 32, 48 are > 3 frames away);
    # the body colours and the PC label colour are present
    assert (np.abs(px.astype(int) - [0x1f, 0x3b, 0x73]).sum(-1) < 30).any()
    assert (np.abs(px.astype(int) - [0x4f, 0x6f, 0xa8]).sum(-1) < 30).any()


def test_mp4_without_ffmpeg_falls_back_to_gif(tmp_path, monkeypatch):
    import convsynth_jax.render as r

    monkeypatch.setattr(r.shutil, "which", lambda name: None)
    t = track_from_motion(load_bvh(BVH).slice(0, 12), "a")
    out = render_animation([Panel("p", (t,))], [], 30.0, tmp_path / "x.mp4")
    assert out.suffix == ".gif" and out.is_file()


def _cfg(*o):
    return compose(["task=render", "progress=false", "jax_cache.dir=null", *o])


def test_render_task_on_a_file_and_a_synthesize_folder(tmp_path):
    s = run_task(_cfg(f"path={BVH}"), tmp_path / "one")
    assert (tmp_path / "one" / "render.gif").is_file() and (tmp_path / "one" / "contact_sheet.png").is_file()
    assert s["frames"][0] == 0 and s["frames"][1] == load_bvh(BVH).num_frames
    # a task=synthesize folder: <character>.bvh + report.json with the transitions
    d = tmp_path / "synth"
    d.mkdir()
    shutil.copy(BVH, d / "female.bvh")
    shutil.copy(BVH2, d / "male.bvh")
    (d / "report.json").write_text(json.dumps({"characters": {"female": {"transitions": [{"frame": 5}, {"frame": 20}]},
                                                              "male": {"success": False}}}))
    s = run_task(_cfg(f"path={d}", "task.duration=1.0"), tmp_path / "two")
    assert s["transitions"] == {"female": [5, 20]}
    assert s["frames"] == [0, 30]
    assert (tmp_path / "two" / "render.gif").is_file()


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
