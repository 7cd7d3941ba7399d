"""Gaze (Sec. 5) with planted positions, AAR validation, and the demo task on the fixtures (and
on real speech when ../shared is present)."""
from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from convsynth_jax.config import compose, run_task
from convsynth_jax.errors import MissingFileError, WalkTalkError
from convsynth_jax.io.bvh import load_bvh
from convsynth_jax.rotations import quat_to_matrix_np
from convsynth_jax.walktalk.gaze import (
    AAREvent,
    apply_gaze,
    envelope,
    statistics_events,
    validate_events,
)
from convsynth_jax.walktalk.params import GazeParams
from convsynth_jax.walktalk.planted_clips import synthetic_jog

FIXTURES = Path(__file__).resolve().parent / "data" / "walktalk"


def _globals(m):
    mats = quat_to_matrix_np(m.rotations)
    g = [None] * m.skeleton.num_joints
    for j, p in enumerate(m.skeleton.parents):
        g[j] = mats[:, j] if p < 0 else g[p] @ mats[:, j]
    return g


def _ry(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


@pytest.fixture(scope="module")
def walker():
    m, _ = synthetic_jog(periods=2.0, bounce=0.0)  # travels along +Z at 10 cm/frame
    return m


def _partner(m, dx, dz):
    hips = np.asarray(m.translations[:, 1], dtype=np.float64).copy()
    return hips + np.array([dx, 0.0, dz])


@pytest.mark.parametrize("r", [1.0, 0.6])
def test_yaw_toward_addressee_beside(walker, r):
    ev = AAREvent("A", "B", 0.2, 0.5, 1.0, 1.5)
    p = GazeParams(r_min=r, r_max=r)
    out, yaw = apply_gaze(walker, "A", [ev], {"B": _partner(walker, 100.0, 0.0)}, p, np.random.default_rng(0))
    g0, g1 = _globals(walker), _globals(out)
    head = walker.skeleton.index("Head")
    t = np.arange(walker.num_frames) / walker.fps
    full = (t >= 0.5) & (t <= 1.0)
    # addressee 1 m to the +X side of a walker heading +Z: theta = +90 deg, scaled by r
    np.testing.assert_allclose(yaw[full], r * np.pi / 2, atol=1e-9)
    for f in np.flatnonzero(full)[::5]:
        np.testing.assert_allclose(g1[head][f] @ g0[head][f].T, _ry(r * np.pi / 2), atol=1e-9)
    np.testing.assert_allclose(yaw[t > 1.5], 0.0)
    np.testing.assert_allclose(out.rotations[t > 1.5], walker.rotations[t > 1.5], atol=1e-12)
    # lower body untouched
    lower = [0, 1, 14, 15, 16, 17, 18, 19, 20, 21]
    np.testing.assert_allclose(out.rotations[:, lower], walker.rotations[:, lower], atol=1e-12)


@pytest.mark.parametrize("ahead_m, lean_deg", [(2.0, 15.0), (1.5, 7.5), (0.8, 0.0), (-2.0, -15.0)])
def test_lean_when_addressee_ahead_or_behind(walker, ahead_m, lean_deg):
    ev = AAREvent("A", "B", 0.0, 0.1, 1.5, 1.6)
    out, yaw = apply_gaze(walker, "A", [ev], {"B": _partner(walker, 0.0, 100.0 * ahead_m)}, GazeParams(),
                          np.random.default_rng(0))
    if ahead_m > 0:
        np.testing.assert_allclose(yaw[5:40], 0.0, atol=1e-9)  # straight ahead: no yaw
    else:
        np.testing.assert_allclose(np.abs(yaw[5:40]), np.pi / 2, atol=1e-9)  # behind: clipped at 90 deg
    g0, g1 = _globals(walker), _globals(out)
    spine = walker.skeleton.index("Spine")
    f = 20
    rel = g1[spine][f] @ g0[spine][f].T @ _ry(-0.2 * yaw[f])  # remove the spine's yaw share, keep the lean
    angle = np.degrees(np.arctan2(rel[2, 1], rel[1, 1]))
    assert angle == pytest.approx(lean_deg, abs=1e-6)


def test_envelope_reached_by_stroke_released_with_retraction():
    e = AAREvent("A", "B", 1.0, 2.0, 3.0, 4.0)
    t = np.array([0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 4.5])
    np.testing.assert_allclose(envelope(t, e), [0, 0, 0.5, 1, 1, 1, 0.5, 0, 0])


def test_aar_errors():
    with pytest.raises(WalkTalkError, match="cannot address itself") as e:
        validate_events([AAREvent("A", "A", 0, 1, 2, 3)], ["A", "B"])
    assert "AAR event 0" in str(e.value)
    with pytest.raises(WalkTalkError, match="unknown character"):
        validate_events([AAREvent("A", "C", 0, 1, 2, 3)], ["A", "B"])
    with pytest.raises(WalkTalkError, match="out of order"):
        validate_events([AAREvent("A", "B", 0, 2, 1, 3)], ["A", "B"])


def test_statistics_events_alternate_and_switch():
    p = GazeParams(gaze_at_s=(2.0, 0.5), gaze_away_s=(1.5, 0.5))
    ev = statistics_events(["A", "B"], 120.0, p, np.random.default_rng(3))
    validate_events(ev, ["A", "B"])
    for c in ("A", "B"):
        mine = [e for e in ev if e.addresser == c]
        assert len(mine) > 10
        # consecutive gaze-at segments (no away in between) never total more than mean + sd + one draw
        run = 0.0
        for a, b in itertools.pairwise(mine):
            run = run + (a.t_end - a.t_begin) if abs(b.t_begin - a.t_end) < 1e-9 else 0.0
            assert run <= 2.5 + 2.0 + 4 * 0.5


def _tsv(path: Path, peaks):
    pd.DataFrame({"peak": peaks}).to_csv(path, sep="\t", index=False)
    return path


def test_demo_on_fixtures_with_peak_tsv(tmp_path):
    a = _tsv(tmp_path / "a.tsv", [2.0, 5.1, 8.3, 12.0])
    b = _tsv(tmp_path / "b.tsv", [3.5, 9.9, 14.2])
    cfg = compose(["task=walktalk_demo", f"walktalk.data_dir={FIXTURES}", "task.duration_s=18",
                   "task.loop_candidates=1", "task.max_gestures=null", "task.video=false",  # video: below
                   f"task.speakers=[{{name: A, peaks_tsv: '{a}'}}, {{name: B, peaks_tsv: '{b}'}}]"])
    out = tmp_path / "out"
    summary = run_task(cfg, out)
    ev = pd.read_csv(out / "walktalk_events.csv")
    assert list(ev.columns[:9]) == ["character", "gesture", "gait", "t_prep_begin", "t_stroke_peak",
                                    "t_retraction_end", "utterance_peak_s", "shift_s", "contact_at_peak"]
    assert len(ev) >= 4 and set(ev["gait"]) == {"walk", "jog"}
    assert ev.loc[ev["single_peak"], "contact_at_peak"].all()
    assert ((ev["shift_s"] <= 0) & (ev["shift_s"] >= -0.6)).all()
    assert (ev["t_stroke_peak"] <= ev["utterance_peak_s"]).all()
    for name in summary["files"]:
        m = load_bvh(out / name)
        assert m.num_frames == 18 * 30
    assert (out / "walktalk_aar.csv").stat().st_size > 0


def test_demo_utterance_outside_timeline_writes_nothing(tmp_path):
    a = _tsv(tmp_path / "a.tsv", [2.0, 25.0])
    b = _tsv(tmp_path / "b.tsv", [3.5])
    cfg = compose(["task=walktalk_demo", f"walktalk.data_dir={FIXTURES}", "task.duration_s=18",
                   "task.loop_candidates=1", "task.max_gestures=null",
                   f"task.speakers=[{{name: A, peaks_tsv: '{a}'}}, {{name: B, peaks_tsv: '{b}'}}]"])
    with pytest.raises(WalkTalkError, match="outside the timeline") as e:
        run_task(cfg, tmp_path / "out")
    assert "a.tsv" in str(e.value)
    assert not list((tmp_path / "out").glob("*.csv")) and not list((tmp_path / "out").glob("*.bvh"))


def test_demo_with_real_speech(tmp_path, speech_dir, bandai_dir):
    cfg = compose(["task=walktalk_demo", f"walktalk.data_dir={bandai_dir}", "task.gaits=[walk]",
                   "task.max_gestures=30", "task.loop_candidates=4", "task.video=false",  # video: below
                   (f"task.speakers=[{{name: A, wav: '{speech_dir / 'acoustic_corpus.wav'}', transcript: '{speech_dir / 'acoustic_corpus.TextGrid'}', offset_s: 1.0}},"
                   f"{{name: B, wav: '{speech_dir / 'cold_corpus.wav'}', transcript: '{speech_dir / 'cold_corpus.TextGrid'}', offset_s: 29.0}}]")])
    summary = run_task(cfg, tmp_path)
    assert summary["utterance_peaks"]["A"] > 3 and summary["gestures_spliced"] > 3
    ev = pd.read_csv(tmp_path / "walktalk_events.csv")
    assert ev.loc[ev["single_peak"], "contact_at_peak"].mean() >= 0.95
    assert ev.loc[ev["single_peak"], "contact_alt_at_peak"].mean() >= 0.95
    assert summary["single_peak_contact_rate_naive"] == pytest.approx(ev.loc[ev["single_peak"], "contact_at_nominal"].mean())
    assert set(ev["character"]) == {"A", "B"}


def _demo_cfg(tmp_path, *extra):
    a = _tsv(tmp_path / "a.tsv", [2.0, 5.1])
    b = _tsv(tmp_path / "b.tsv", [3.5])
    return compose(["task=walktalk_demo", f"walktalk.data_dir={FIXTURES}", "task.duration_s=8", "task.gaits=[walk]",
                    "task.loop_candidates=1", "task.video_fps=2", *extra,
                    f"task.speakers=[{{name: A, peaks_tsv: '{a}', wav: '{tmp_path / 'nowhere.wav'}'}}, "
                    f"{{name: B, peaks_tsv: '{b}'}}]"])


def test_demo_video_missing_speech_names_the_file_and_writes_nothing(tmp_path):
    """A speaker's speech recording that is not there stops the demo before anything is written."""
    with pytest.raises(MissingFileError, match="nowhere.wav"):
        run_task(_demo_cfg(tmp_path), tmp_path / "out")
    assert not list((tmp_path / "out").iterdir())


def test_demo_video_unwritable_path_is_a_clear_error(tmp_path):
    """A video path that cannot be written (its folder is a file) is refused before any work, naming
    the path; nothing is written."""
    (tmp_path / "taken").write_text("a file, not a folder")
    (tmp_path / "nowhere.wav").write_bytes(b"")   # never read: the path check comes first
    with pytest.raises(WalkTalkError, match="cannot write the demo video") as e:
        run_task(_demo_cfg(tmp_path, f"task.video_file={tmp_path / 'taken' / 'demo.mp4'}"), tmp_path / "out")
    assert "taken/demo.mp4" in str(e.value)
    assert not list((tmp_path / "out").iterdir())
    with pytest.raises(WalkTalkError, match="MP4"):
        run_task(_demo_cfg(tmp_path, "task.video_file=demo.gif"), tmp_path / "out")


def test_speech_wav_places_each_recording_at_its_offset(tmp_path):
    """The demo's speech track (tasks.converse.write_stereo with offsets): planted ramps, one starting
    0.5 s in (silence before it), one whose first 0.25 s fall before the timeline (dropped), one
    missing speaker (silent); B at another rate is resampled onto A's."""
    from convsynth_jax.io.audio import Audio, load_audio
    from convsynth_jax.tasks.converse import write_stereo

    rate = 8000
    a = Audio(np.linspace(-0.5, 0.5, rate).astype(np.float32), rate)
    x = load_audio(write_stereo(tmp_path / "a.wav", a, None, 2.0, offsets_s=(0.5, 0.0))).samples
    assert x.shape == (2 * rate, 2) and np.abs(x[:rate // 2]).max() == 0 and np.abs(x[:, 1]).max() == 0
    np.testing.assert_allclose(x[rate // 2:rate // 2 + rate, 0], a.samples, atol=1e-4)
    assert np.abs(x[rate // 2 + rate:, 0]).max() == 0
    b = Audio(np.linspace(0.0, 0.4, 2 * rate).astype(np.float32), 2 * rate)   # 1 s at twice the rate
    x = load_audio(write_stereo(tmp_path / "b.wav", a, b, 1.0, offsets_s=(-0.25, 0.0))).samples
    np.testing.assert_allclose(x[:3 * rate // 4, 0], a.samples[rate // 4:], atol=1e-4)
    assert np.abs(x[3 * rate // 4:, 0]).max() == 0
    np.testing.assert_allclose(x[:, 1], np.interp(np.arange(rate) / rate, np.arange(2 * rate) / (2 * rate), b.samples),
                               atol=1e-4)


def test_demo_video_camera_follows_the_pair_and_looks_along_the_walk():
    """Planted: two walkers 1 m apart along X, advancing along +Z at different speeds, each under a
    static top joint left at the start (bandai2's joint_Root). The camera keeps the mean of their
    hips at the origin on the ground (heights kept), draws the static joint at the hips, and the view
    has X across (a pair drifting apart along Z would otherwise turn it towards a side view)."""
    from convsynth_jax.render import DrawnBody, three_quarter_camera
    from convsynth_jax.tasks.walktalk_demo import _follow_pair

    t = np.arange(30, dtype=np.float64)
    parents = (-1, 0, 1)   # static root -> hips -> head

    def walker(x, speed):
        pos = np.zeros((len(t), 3, 3))
        pos[:, 0] = (x, 0.0, 0.0)
        pos[:, 1] = np.stack([x + 2 * np.sin(t), 90 + np.cos(t), speed * t], axis=1)
        pos[:, 2] = pos[:, 1] + (0.0, 60.0, 0.0)
        return DrawnBody(pos, parents, head=2)

    a, b = walker(-50.0, 40.0), walker(50.0, 48.0)
    fa, fb = _follow_pair((a, b), [1, 1])
    centre = (fa.positions[:, 1] + fb.positions[:, 1]) / 2
    np.testing.assert_allclose(centre[:, [0, 2]], 0.0, atol=1e-9)
    np.testing.assert_allclose(fa.positions[:, 1, 1], a.positions[:, 1, 1])          # heights kept
    np.testing.assert_allclose(fb.positions[:, 1, 0] - fa.positions[:, 1, 0], 100.0)  # 1 m apart across
    np.testing.assert_allclose(fa.positions[:, 0], fa.positions[:, 1])                # static root at the hips
    np.testing.assert_allclose(fa.positions[:, 2] - fa.positions[:, 1], a.positions[:, 2] - a.positions[:, 1])
    free = three_quarter_camera([fa, fb], 100, 100, yaw_deg=0.0, pitch_deg=0.0)
    assert abs(free.right[2]) > 0.5                          # the drift along Z turns the view without the direction
    cam = three_quarter_camera([fa, fb], 100, 100, yaw_deg=0.0, pitch_deg=0.0, across=(1.0, 0.0, 0.0))
    np.testing.assert_allclose(cam.right, [1.0, 0.0, 0.0], atol=1e-12)               # as the demo's video has it
    np.testing.assert_allclose(abs(cam.view[2]), 1.0, atol=1e-12)                     # looking along the walk
