"""CDBN features, constraint files, model files, synthesis helpers and the errors they raise."""
from __future__ import annotations

import numpy as np
import pytest

from convsynth_jax.cdbn.features import (
    FEATURE_LAYOUT,
    check_lengths,
    head_euler_to_quat,
    head_rotation,
    head_rotation_from_quat,
    read_constraints,
    speech_features,
)
from convsynth_jax.cdbn.params import DBNModel, CDBNFeatureParams
from convsynth_jax.errors import CDBNError, ConvSynthError
from convsynth_jax.io.audio import Audio

NAMES = ("other", "nod", "shake")


def voice(seconds=3.0, f0=150.0, sr=16000, seed=0):
    from convsynth_jax.data.synthetic import Segment, _render_voice

    rng = np.random.default_rng(seed)
    words, t = [], 0.2
    while t < seconds - 0.5:
        words.append((t, t + 0.3, "w", False))
        t += 0.35
    seg = Segment("a", "PC", words[0][0], words[-1][1], 1.0, words)
    sig, planted = _render_voice([seg], f0, seconds, sr, rng, 0.28)
    return Audio(sig.astype(np.float32), sr, "voice.wav"), planted


def test_speech_features_shape_and_f0_track_planted_contour():
    audio, planted = voice()
    x = speech_features(audio, CDBNFeatureParams(), num_frames=90, fps=30.0)
    assert x.shape == (90, 6) and np.all(np.isfinite(x))
    # frames in the middle of voiced words: Praat F0 within 5% of the planted contour
    t = np.arange(90) / 30.0
    idx = (t * 16000).astype(int)
    v = planted[idx] > 0
    inner = v & np.roll(v, 2) & np.roll(v, -2)
    rel = np.abs(x[inner, 0] - planted[idx][inner]) / planted[idx][inner]
    assert np.median(rel) < 0.05
    # derivatives are derivatives: first-derivative column ~ gradient of the F0 column (per second)
    assert np.corrcoef(np.gradient(x[:, 0], 1 / 30.0)[inner], x[inner, 2])[0, 1] > 0.8


def test_too_few_voiced_frames_suggests_lower_floor():
    rng = np.random.default_rng(0)
    noise = Audio((0.1 * rng.standard_normal(32000)).astype(np.float32), 16000, "noise.wav")
    with pytest.raises(CDBNError, match="lower F0 floor") as e:
        speech_features(noise, CDBNFeatureParams(f0_floor=75.0))
    assert "noise.wav" in str(e.value)


def test_creaky_voice_needs_the_adaptive_floor(speech_dir):
    from convsynth_jax.io.audio import load_audio

    audio = load_audio(speech_dir / "cold_corpus.wav")
    with pytest.raises(CDBNError, match="lower F0 floor"):
        speech_features(audio, CDBNFeatureParams(f0_floor=75.0))
    x = speech_features(audio, CDBNFeatureParams(f0_floor="auto"))
    assert x.shape == (round(audio.duration * 30), 6) and np.all(np.isfinite(x))


def test_length_mismatch_names_both_files():
    check_lengths(np.zeros(100), np.zeros(101), "a.wav", "a.bvh")   # one frame is tolerated
    with pytest.raises(CDBNError) as e:
        check_lengths(np.zeros(100), np.zeros(103), "a.wav", "a.bvh")
    assert "a.wav" in str(e.value) and "a.bvh" in str(e.value)


def test_constraint_file_errors(tmp_path):
    f = tmp_path / "c.tsv"
    f.write_text("start\tend\tlabel\n0.5\t1.0\tnod\n1.2\t1.5\tshake\n")
    c = read_constraints(f, NAMES, 60, 30.0)
    assert (c[15:30] == 1).all() and (c[36:45] == 2).all() and c[0] == 0 and c[31] == 0
    f.write_text("0.5\t1.0\tnod\n1.2\t1.5\twave\n")
    with pytest.raises(CDBNError, match="line 2") as e:
        read_constraints(f, NAMES, 60, 30.0)
    assert "wave" in str(e.value) and "'shake'" in str(e.value)          # lists the known labels
    f.write_text("0.5\t1.0\tnod\n0.9\t1.5\tshake\n")
    with pytest.raises(CDBNError, match="overlaps") as e:
        read_constraints(f, NAMES, 60, 30.0)
    assert "line 2" in str(e.value)


def test_nan_features_name_the_frame():
    from convsynth_jax.cdbn.synthesize import state_posteriors

    K = 2
    m = DBNModel(np.zeros((K, 9)), np.broadcast_to(np.eye(9), (K, 9, 9)).copy(), np.full((1, K), 0.5),
                 np.full((1, K, K), 0.5), tuple(range(6)), (6, 7, 8), ("all",), FEATURE_LAYOUT)
    s = np.zeros((20, 6))
    s[7, 3] = np.nan
    with pytest.raises(CDBNError, match="frame 7"):
        state_posteriors(m, s)


def test_model_file_roundtrip_and_layout_check(tmp_path):
    from convsynth_jax.cdbn.modelio import load_model, save_model

    K = 3
    rng = np.random.default_rng(0)
    m = DBNModel(rng.normal(size=(K, 9)), np.broadcast_to(np.eye(9), (K, 9, 9)).copy(), np.full((2, K), 1 / 3),
                 np.full((2, K, K), 1 / 3), tuple(range(6)), (6, 7, 8), ("other", "nod"), FEATURE_LAYOUT)
    save_model(tmp_path / "m.npz", m, motion_mean=np.zeros(3))
    back, extra = load_model(tmp_path / "m.npz", FEATURE_LAYOUT)
    np.testing.assert_array_equal(back.means, m.means)
    assert back.constraint_names == ("other", "nod") and "motion_mean" in extra
    other = FEATURE_LAYOUT[:6] + ("arm_l", "arm_r", "forearm")
    with pytest.raises(CDBNError, match="feature layout"):
        load_model(tmp_path / "m.npz", other)
    with pytest.raises(ConvSynthError):
        load_model(tmp_path / "missing.npz")


def test_head_rotation_round_trip_and_keypoint_smoothing():
    from convsynth_jax.cdbn.semisynthetic import head_motion
    from convsynth_jax.cdbn.synthesize import keypoint_smooth

    t = np.arange(90) / 30.0
    ang = np.stack([10 * np.sin(2 * np.pi * 0.5 * t), 15 * np.cos(2 * np.pi * 0.3 * t), 3 * np.sin(t)], axis=1)
    np.testing.assert_allclose(head_rotation_from_quat(head_euler_to_quat(ang)), ang, atol=1e-9)
    # the Head joint carries the angles on top of the neck's rest rotation: features see neck * head
    mo = head_motion(ang, 30.0, "x")
    feat = head_rotation(mo, CDBNFeatureParams(head_joints=("Head",)))
    np.testing.assert_allclose(feat, ang, atol=1e-4)
    # smoothing keeps the key points exactly and stays close on a slow trajectory
    q = keypoint_smooth(ang, 30.0, 15.0)
    sm = head_rotation_from_quat(q)
    np.testing.assert_allclose(sm[::2], ang[::2], atol=1e-6)
    assert np.abs(sm - ang).max() < 0.2
    # ... but removes a frame-rate zigzag between key points
    zig = ang.copy()
    zig[1::2, 0] += 5.0
    assert np.abs(head_rotation_from_quat(keypoint_smooth(zig, 30.0, 15.0))[1::2, 0] - zig[1::2, 0]).max() > 4.0
