"""corpus=beat2: BEAT2's layout as pseudo-dyads (io/beat2.py), on a fabricated folder and the shared take."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy.io import wavfile

from conftest import shared_path
from convsynth_jax.config import compose, to_params
from convsynth_jax.errors import ConfigError, CorpusError, MissingFileError
from convsynth_jax.io.beat2 import load_beat2
from convsynth_jax.io.transcripts import save_textgrid
from convsynth_jax.tasks.common import open_corpus, pairing_note

WORDS = pd.DataFrame({"start": [0.0, 2.5], "end": [0.5, 3.0], "word": ["hello", "world"]})   # 4 s TextGrid


def make_take(root, take, T=120, seed=0):
    rng = np.random.default_rng(seed)
    for d in ("smplxflame_30", "wave16k", "textgrid"):
        (root / d).mkdir(parents=True, exist_ok=True)
    np.savez(root / "smplxflame_30" / f"{take}.npz", poses=rng.normal(0, 0.3, (T, 165)).astype(np.float32),
             trans=np.cumsum(rng.normal(0, 0.01, (T, 3)), 0), betas=np.zeros(300, np.float32),
             mocap_frame_rate=np.int32(30))
    wavfile.write(root / "wave16k" / f"{take}.wav", 16000,
                  (0.1 * np.sin(np.arange(T * 16000 // 30) / 10.0)).astype(np.float32))
    save_textgrid(WORDS, root / "textgrid" / f"{take}.TextGrid", duration=4.0)


def test_single_take_is_a_pseudo_dyad_with_a_shifted_copy(tmp_path):
    root = tmp_path / "beat2"
    make_take(root, "2_scott_0_1_1")
    c = load_beat2(root, derived_dir=tmp_path / "derived")
    assert c.metadata["pairing"] == "pseudo_dyad" and c.metadata["partner_statistics"] == "null control"
    (s,) = c.sessions
    a, b = s.participants
    assert (a.character, b.character) == ("scott", "scott_shifted")
    ma, mb = a.load_motion(30), b.load_motion(30)
    assert ma.num_frames == mb.num_frames == 120
    assert np.allclose(np.roll(ma.rotations, -60, axis=0), mb.rotations, atol=1e-6)   # half the take
    wa, wb = a.load_transcript(), b.load_transcript()
    assert list(wa["word"]) == ["hello", "world"]
    assert list(wb["word"]) == ["hello", "world"][::-1]        # hello at 2.0 s after the shift, world at 0.5 s
    assert np.allclose(wb["start"], [0.5, 2.0])
    assert abs(b.load_audio().duration - a.load_audio().duration) < 1e-3
    # written once: a second load reuses the copy
    mtime = b.motion_path.stat().st_mtime_ns
    assert load_beat2(root, derived_dir=tmp_path / "derived").sessions[0].participants[1].motion_path.stat().st_mtime_ns == mtime


def test_two_takes_pair_and_characters_override(tmp_path):
    root = tmp_path / "beat2"
    make_take(root, "2_scott_0_1_1")
    make_take(root, "4_lawrence_0_2_2", seed=1)
    cfg = compose(["corpus=beat2", f"corpus.root={root}", "+corpus.characters.interloctr=bob",
                   f"cache_dir={tmp_path / 'cache'}"])
    c = open_corpus(to_params(cfg))
    (s,) = c.sessions
    assert [p.character for p in s.participants] == ["scott", "bob"]
    assert [p.motion_path.stem for p in s.participants] == ["2_scott_0_1_1", "4_lawrence_0_2_2"]
    assert pairing_note(c)["partner_statistics"] == "null control"


def test_bad_folders_name_the_file(tmp_path):
    with pytest.raises(MissingFileError, match="nowhere"):
        load_beat2(tmp_path / "nowhere")
    root = tmp_path / "b"
    make_take(root, "2_scott_0_1_1")
    (root / "wave16k" / "2_scott_0_1_1.wav").unlink()
    with pytest.raises(MissingFileError, match=r"2_scott_0_1_1.wav.*no audio"):
        load_beat2(root, derived_dir=tmp_path / "d")
    make_take(root, "2_scott_0_1_1")
    (root / "textgrid" / "2_scott_0_1_1.TextGrid").unlink()
    with pytest.raises(MissingFileError, match="TextGrid.*no word alignment"):
        load_beat2(root, derived_dir=tmp_path / "d")
    make_take(root, "2_scott_0_1_1")
    make_take(root, "scott")
    with pytest.raises(CorpusError, match="scott.npz"):
        load_beat2(root, derived_dir=tmp_path / "d")
    with pytest.raises(ConfigError, match="pairing"):
        load_beat2(root, pairing="dyad")


def test_shared_take_loads(tmp_path):
    root = shared_path("beat2")
    c = load_beat2(root, derived_dir=tmp_path / "d")
    a, b = c.sessions[0].participants
    assert a.character == "scott" and len(a.load_transcript()) == 199
    assert a.load_motion(30).num_frames == 1906 and "right_thumb3" in a.load_motion(30).skeleton.names


def test_build_graph_on_a_beat2_folder(tmp_path):
    """task=build_graph corpus=beat2 wires through: one graph per character, the null-control flag."""
    import json

    from convsynth_jax.config import run_task

    root = tmp_path / "beat2"
    make_take(root, "2_scott_0_1_1", T=300)
    s = run_task(compose(["task=build_graph", "corpus=beat2", f"corpus.root={root}", f"cache_dir={tmp_path / 'c'}",
                          "progress=false"]), tmp_path / "out")
    assert set(s["graphs"]) == {"scott", "scott_shifted"} and s["partner_statistics"] == "null control"
    assert (tmp_path / "out" / "graph_scott.npz").is_file()
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["pairing"] == "pseudo_dyad"


def test_corpus_smplx_model_gives_rest_joints(tmp_path):
    from convsynth_jax.io.smplx import SMPLX_TEMPLATE_JOINTS

    root = tmp_path / "beat2"
    make_take(root, "2_scott_0_1_1")
    rng = np.random.default_rng(3)
    jr = rng.random((55, 30))
    jr /= jr.sum(1, keepdims=True)
    vt = rng.normal(0, 0.3, (30, 3))
    np.savez(tmp_path / "SMPLX_FAKE.npz", J_regressor=jr, v_template=vt, shapedirs=np.zeros((30, 3, 10)))
    cfg = compose(["corpus=beat2", f"corpus.root={root}", f"corpus.smplx_model={tmp_path / 'SMPLX_FAKE.npz'}",
                   f"cache_dir={tmp_path / 'cache'}"])
    m = open_corpus(to_params(cfg)).sessions[0].participants[0].load_motion(30)
    rest = jr @ vt
    j = m.skeleton.index("left_wrist")
    assert np.allclose(m.skeleton.offsets[j], (rest[20] - rest[18]) * 100)
    assert not np.allclose(m.skeleton.offsets[j], (SMPLX_TEMPLATE_JOINTS[20] - SMPLX_TEMPLATE_JOINTS[18]) * 100)
