"""Gestures from the core system's synthesized conversation (walktalk/conversation_gestures.py, ours): the
retargeting by joint role against planted bone directions, the movement segmentation against
planted movements, and the demo end to end on the tiny corpus's synthesized conversation."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from convsynth_jax.config import compose, run_task
from convsynth_jax.data.skeleton_seated import INDEX, base_pose_degrees, seated_skeleton
from convsynth_jax.errors import ConvSynthError
from convsynth_jax.io.bvh import load_bvh
from convsynth_jax.rotations import euler_deg_to_quat_np
from convsynth_jax.skeleton import Motion
from convsynth_jax.kinematics import forward_kinematics_np
from convsynth_jax.walktalk.body import find_body
from convsynth_jax.walktalk.conversation_gestures import SegmentParams, movement_runs, retarget_arms

FIXTURES = Path(__file__).resolve().parent / "data" / "walktalk"


def _seated_motion(euler_deg: np.ndarray, fps: float = 30.0) -> Motion:
    """(F, J, 3) Z, X, Y degrees on the seated skeleton -> Motion (hips 48 cm up, static)."""
    sk = seated_skeleton()
    f = euler_deg.shape[0]
    rot = euler_deg_to_quat_np(euler_deg, "ZXY")
    tr = np.broadcast_to(sk.offsets, (f, sk.num_joints, 3)).copy()
    tr[:, 0] = (0.0, 48.0, 0.0)
    return Motion(sk, rot, tr, fps, "seated")


def _frame(pos, hips, neck, left, right):
    """Torso frame written out independently of the module: Gram-Schmidt of (left - right) against
    (neck - hips), then their cross product."""
    out = []
    for p in pos:
        up = p[neck] - p[hips]
        up = up / np.linalg.norm(up)
        lat = p[left] - p[right]
        lat = lat - lat.dot(up) * up
        lat = lat / np.linalg.norm(lat)
        out.append(np.column_stack([lat, up, np.cross(lat, up)]))
    return np.array(out)


@pytest.fixture(scope="module")
def bandai():
    m = load_bvh(FIXTURES / "dataset-2_raise-up-right-hand_normal_001_f0-59.bvh")
    return m, find_body(m.skeleton)


def test_retarget_carries_bone_directions_in_the_torso_frame(bandai):
    """Planted: random arm poses on the seated Mixamo-named rig. On the Bandai rig every upper arm
    and forearm points where the source's does, both read in their own torso frames; torso, legs,
    collars and hands keep the template's first frame."""
    template, body = bandai
    rng = np.random.default_rng(5)
    f = 12
    e = np.broadcast_to(base_pose_degrees(), (f, len(INDEX), 3)).copy()
    for side in ("Left", "Right"):
        e[:, INDEX[f"{side}Arm"]] += rng.uniform(-60, 60, (f, 3))
        e[:, INDEX[f"{side}ForeArm"]] += rng.uniform(-50, 50, (f, 3))
    e[:, INDEX["Spine1"]] += rng.uniform(-15, 15, (f, 3))   # the torso turns: directions are torso-relative
    src = _seated_motion(e)
    out = retarget_arms(src, template, body)
    assert out.skeleton is template.skeleton and out.num_frames == f
    sp, tp = forward_kinematics_np(src), forward_kinematics_np(out)
    s = {k: INDEX[k] for k in ("Hips", "Neck", "LeftArm", "RightArm", "LeftForeArm", "RightForeArm", "LeftHand",
                               "RightHand")}
    fs = _frame(sp, s["Hips"], s["Neck"], s["LeftArm"], s["RightArm"])
    j = body.joints
    ft = _frame(tp, j["hips"], j["neck"], j["upperarm_l"], j["upperarm_r"])
    for side, full in (("l", "Left"), ("r", "Right")):
        for (sa, sb), (ta, tb) in ((( f"{full}Arm", f"{full}ForeArm"), (f"upperarm_{side}", f"elbow_{side}")),
                                   ((f"{full}ForeArm", f"{full}Hand"), (f"elbow_{side}", f"hand_{side}"))):
            ds = np.einsum("fba,fb->fa", fs, sp[:, s[sb]] - sp[:, s[sa]])
            dt = np.einsum("fba,fb->fa", ft, tp[:, j[tb]] - tp[:, j[ta]])
            cos = np.sum(ds * dt, -1) / np.linalg.norm(ds, axis=-1) / np.linalg.norm(dt, axis=-1)
            assert np.degrees(np.arccos(np.clip(cos, -1, 1))).max() < 0.01   # float32 rotations
    keep = [k for k in range(template.skeleton.num_joints)
            if k not in (j["upperarm_l"], j["upperarm_r"], j["elbow_l"], j["elbow_r"])]
    np.testing.assert_array_equal(np.asarray(out.rotations)[:, keep],
                                  np.broadcast_to(np.asarray(template.rotations)[0, keep], (f, len(keep), 4)))


def test_movement_runs_find_planted_movements():
    """Planted: the right forearm swings over frames 30-59 and the left over 120-164, still
    otherwise (the seated base pose): two runs, each inside its planted span."""
    f = 220
    e = np.broadcast_to(base_pose_degrees(), (f, len(INDEX), 3)).copy()
    t = np.arange(30)
    e[30:60, INDEX["RightForeArm"], 1] += 40 * np.sin(np.pi * t / 29)
    t = np.arange(45)
    e[120:165, INDEX["LeftForeArm"], 1] += 30 * np.sin(np.pi * t / 44)
    runs = movement_runs(_seated_motion(e), SegmentParams())
    assert len(runs) == 2
    (a0, b0), (a1, b1) = runs
    assert 29 <= a0 < 36 and 54 < b0 <= 61
    assert 119 <= a1 < 128 and 157 < b1 <= 166


@pytest.fixture(scope="module")
def synthesized_dir(tiny_corpus_dir, tiny_cache_dir, tmp_path_factory):
    """task=synthesize on the tiny corpus: one BVH per character (relaxed matching, so the window
    is solved)."""
    syn = tmp_path_factory.mktemp("syn")
    s = run_task(compose(["task=synthesize", "corpus=synthetic_tiny", f"corpus.root={tiny_corpus_dir}",
                          f"cache_dir={tiny_cache_dir('synthesize_cache')}", "progress=false", "task.start=14",
                          "task.duration=10", "search.matching=labels"]), syn)
    assert s["success"]
    return syn


def test_demo_walks_the_synthesized_conversation(synthesized_dir, tmp_path):
    """End to end on the tiny corpus: task=synthesize writes one BVH per character, the demo cuts
    gestures from them (gesture_source=synthesized) and splices them, at their own times, onto the
    fixture loops, synchronized to the footsteps."""
    syn = synthesized_dir
    chars = sorted(p.stem for p in syn.glob("*.bvh"))
    assert len(chars) == 2
    out = tmp_path / "demo"
    summary = run_task(compose(["task=walktalk_demo", f"walktalk.data_dir={FIXTURES}", "task.duration_s=14",
                                "task.loop_candidates=1", "task.gesture_source=synthesized",
                                f"task.synthesized_dir={syn}", f"task.synthesized_characters=[{','.join(chars)}]",
                                "task.speakers=[{name: A, offset_s: 1.0}, {name: B, offset_s: 2.0}]"]), out)
    assert summary["gesture_source"] == "synthesized"
    info = summary["synthesized"]
    assert sum(v["gestures"] for v in info.values()) >= 1
    ev = pd.read_csv(out / "walktalk_events.csv")
    assert len(ev) >= 1 and set(ev["gait"]) <= {"walk", "jog"}
    for r in ev.itertuples():
        char = chars[["A", "B"].index(r.character)]
        assert r.gesture.startswith(f"{char}@")          # each speaker gestures with its own character's motion
        start_ms = int(r.gesture.split("@")[1][:-2])
        offset = 1.0 if r.character == "A" else 2.0
        assert offset + start_ms / 1000 <= r.t_stroke_peak <= offset + 10.0   # at its own time, not drawn
    assert ev.loc[ev["single_peak"], "contact_at_peak"].all()
    assert ((ev["shift_s"] <= 0) & (ev["shift_s"] >= -0.6)).all()
    for name in summary["files"]:
        assert load_bvh(out / name).num_frames == 14 * 30
    json.dumps(summary, default=str)


def test_synthesized_gestures_on_speech_peaks(synthesized_dir, tmp_path):
    """synthesized_timing=speech: the synthesized character's gestures drawn per stress peak of a
    peak TSV, never another character's."""
    peaks = tmp_path / "b.tsv"
    pd.DataFrame({"peak": [2.0, 4.5, 7.0, 9.5]}).to_csv(peaks, sep="\t", index=False)
    chars = sorted(p.stem for p in synthesized_dir.glob("*.bvh"))
    out = tmp_path / "demo"
    run_task(compose(["task=walktalk_demo", f"walktalk.data_dir={FIXTURES}", "task.duration_s=12",
                      "task.loop_candidates=1", "task.gaits=[walk]", "task.gesture_source=synthesized",
                      "task.synthesized_timing=speech", f"task.synthesized_dir={synthesized_dir}",
                      f"task.synthesized_characters=[{chars[1]},{chars[1]}]",
                      f"task.speakers=[{{name: A, peaks_tsv: '{peaks}'}}, {{name: B, peaks_tsv: '{peaks}'}}]"]), out)
    ev = pd.read_csv(out / "walktalk_events.csv")
    assert len(ev) >= 2 and ev["gesture"].str.startswith(f"{chars[1]}@").all()
    assert (ev["t_stroke_peak"] <= ev["utterance_peak_s"]).all()


def test_synthesized_source_needs_its_folder(tmp_path):
    cfg = compose(["task=walktalk_demo", f"walktalk.data_dir={FIXTURES}", "task.gesture_source=synthesized",
                   f"task.synthesized_dir={tmp_path / 'nowhere'}", "task.loop_candidates=1",
                   "task.speakers=[{name: A}, {name: B}]"])
    with pytest.raises(ConvSynthError, match="synthesized_dir"):
        run_task(cfg, tmp_path / "out")
    cfg = compose(["task=walktalk_demo", f"walktalk.data_dir={FIXTURES}", "task.gesture_source=clips"])
    with pytest.raises(ConvSynthError, match="gesture_source"):
        run_task(cfg, tmp_path / "out2")


def test_demo_video_carries_both_speakers_speech(synthesized_dir, tmp_path):
    """The demo on the synthesized conversation writes a video with an audio stream, as long as the
    motion (within one motion frame), and the speech WAV under it holds each character's input
    audio (task=synthesize's <role>_input.wav) from its speaker's offset on: A left, B right."""
    from convsynth_jax.io.audio import load_audio
    from convsynth_jax.render import probe_streams

    chars = sorted(p.stem for p in synthesized_dir.glob("*.bvh"))
    out = tmp_path / "demo"
    duration, offsets = 6.0, (0.5, 1.25)
    summary = run_task(compose(["task=walktalk_demo", f"walktalk.data_dir={FIXTURES}", f"task.duration_s={duration}",
                                "task.loop_candidates=1", "task.gaits=[walk]", "task.video_fps=2",
                                "task.gesture_source=synthesized", f"task.synthesized_dir={synthesized_dir}",
                                f"task.synthesized_characters=[{','.join(chars)}]",
                                f"task.speakers=[{{name: A, offset_s: {offsets[0]}}}, {{name: B, offset_s: {offsets[1]}}}]"]),
                       out)
    assert summary["video"]["speakers_with_audio"] == ["A", "B"]
    streams = probe_streams(out / "walktalk_demo.mp4")
    assert streams["video"] == 1 and streams["audio"] == 1
    frames = load_bvh(out / "A_walk.bvh").num_frames
    assert abs(streams["duration"] - frames / 30.0) <= 1 / 30.0
    roles = {c: e["role"] for c, e in json.loads((synthesized_dir / "report.json").read_text())["characters"].items()}
    wav = load_audio(out / "walktalk_speech.wav")
    rate = wav.sample_rate
    assert wav.samples.shape == (round(duration * rate), 2)
    for ch, (char, off) in enumerate(zip(chars, offsets)):
        src = load_audio(synthesized_dir / f"{roles[char]}_input.wav")
        assert src.sample_rate == rate
        k = round(off * rate)
        got = wav.samples[:, ch]
        want = np.asarray(src.samples, np.float64)[:len(got) - k]
        assert np.abs(got[:k]).max() == 0                       # silent before the speaker's offset
        np.testing.assert_allclose(got[k:k + len(want)], want, atol=1 / 32767 + 1e-6)   # 16-bit PCM
        assert np.abs(want).max() > 0.01                         # and there is speech to carry
