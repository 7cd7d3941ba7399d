"""Faults while writing and numerical faults in data: a read-only folder or a full
disk gives the project's WriteError naming the file and leaves no partial result visible; NaN frames,
empty or silent audio and single-frame clips give clear errors or the documented handling
(docs/reliability.md)."""
from __future__ import annotations

import errno
import os
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from convsynth_jax.errors import AudioFormatError, BVHFormatError, WriteError
from convsynth_jax.utils import write_json_atomic, write_text_atomic


def _full_disk_after(n_bytes: int):
    """A Path.write_text / write_bytes that writes ``n_bytes`` and then fails as a full disk does."""
    def write(self, data, *a, **k):
        with open(self, "wb") as fh:
            fh.write((data.encode() if isinstance(data, str) else data)[:n_bytes])
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(self))
    return write


def _visible(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.rglob("*") if not p.name.endswith(".lock"))


def test_full_disk_keeps_the_previous_file_and_leaves_no_temporary(tmp_path, monkeypatch):
    target = tmp_path / "summary.json"
    write_json_atomic(target, {"old": 1})
    monkeypatch.setattr(Path, "write_text", _full_disk_after(5))
    with pytest.raises(WriteError, match=r"summary\.json: cannot write \(the disk is full") as info:
        write_json_atomic(target, {"new": 2})
    assert info.value.errno == errno.ENOSPC and isinstance(info.value, OSError)
    monkeypatch.undo()
    assert target.read_text().strip().replace(" ", "").replace("\n", "") == '{"old":1}'
    assert _visible(tmp_path) == ["summary.json"]


def test_read_only_folder_gives_write_error(tmp_path, monkeypatch):
    def read_only(*a, **k):
        raise OSError(errno.EROFS, os.strerror(errno.EROFS))
    monkeypatch.setattr(tempfile, "mkstemp", read_only)
    with pytest.raises(WriteError, match=r"table\.md: cannot write \(the file system is read-only"):
        write_text_atomic(tmp_path / "out" / "table.md", "x")


@pytest.mark.skipif(hasattr(os, "geteuid") and os.geteuid() == 0, reason="root writes into read-only folders")
def test_real_read_only_folder(tmp_path):
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o500)
    try:
        with pytest.raises(WriteError, match="no permission"):
            write_text_atomic(folder / "table.md", "x")
        assert _visible(folder) == []
    finally:
        folder.chmod(0o700)


def test_task_output_on_a_full_disk(tmp_path, monkeypatch):
    """A task whose summary cannot be written: the WriteError names summary.json, no summary is left."""
    from convsynth_jax.config import compose, run_task
    from convsynth_jax.testing.fuzz import _motion
    from convsynth_jax.io.bvh import save_bvh

    clip = save_bvh(_motion(10), tmp_path / "clip.bvh")
    cfg = compose(["task=inspect", f"path={clip}", "jax_cache.dir=null"])
    out = tmp_path / "out"
    monkeypatch.setattr(Path, "write_text", _full_disk_after(10))
    with pytest.raises(WriteError, match=r"summary\.json: cannot write \(the disk is full"):
        run_task(cfg, out)
    monkeypatch.undo()
    assert _visible(out) == []


def test_results_store_on_a_full_disk_leaves_no_entry(tmp_path, monkeypatch):
    from convsynth_jax.evaluation.store import ResultStore

    store = ResultStore(tmp_path / "store")
    cases = pd.DataFrame({"fold": [0], "success": [True]})

    def full(self, *a, **k):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    monkeypatch.setattr(pd.DataFrame, "to_csv", full)
    with pytest.raises(WriteError, match="the disk is full"):
        store.write("k1", cases, {"fold": 0})
    monkeypatch.undo()
    assert store.keys() == [] and store.read("k1") is None
    assert _visible(store.root) == []
    store.write("k1", cases, {"fold": 0})   # room again: the entry is written whole
    assert store.keys() == ["k1"] and store.read("k1").record["fold"] == 0


def test_synthetic_corpus_on_a_full_disk_leaves_no_folder(tmp_path, monkeypatch):
    from convsynth_jax.data import ensure_synthetic_corpus
    from convsynth_jax.io import audio

    def full(path, *a, **k):
        Path(path).write_bytes(b"RIFF")  # half a file, then the disk is full
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))
    monkeypatch.setattr(audio.wavfile, "write", full)
    gen = {"seed": 1, "num_sessions": 1, "session_seconds": 10.0, "calibrate_rates": False, "quota_planting": False}
    with pytest.raises(WriteError, match=r"\.wav: cannot write \(the disk is full"):
        ensure_synthetic_corpus({"name": "tiny", "root": None, "generator": gen}, tmp_path)
    assert _visible(tmp_path) == []


# Numerical faults in data

def test_nan_frame_mid_file_names_the_frame(tmp_path):
    from convsynth_jax.io.bvh import load_bvh, save_bvh
    from convsynth_jax.testing.fuzz import _motion

    lines = save_bvh(_motion(30), tmp_path / "clip.bvh").read_text().splitlines()
    first = next(i for i, line in enumerate(lines) if line.startswith("Frame Time")) + 1
    vals = lines[first + 17].split()
    vals[4] = "nan"
    lines[first + 17] = " ".join(vals)
    (tmp_path / "clip.bvh").write_text("\n".join(lines) + "\n")
    with pytest.raises(BVHFormatError, match=r"clip\.bvh: .*frame 17: non-finite value in channel 4"):
        load_bvh(tmp_path / "clip.bvh")


def test_zero_length_audio_is_an_error(tmp_path):
    from scipy.io import wavfile

    from convsynth_jax.io.audio import load_audio

    wavfile.write(tmp_path / "empty.wav", 16000, np.zeros(0, np.int16))
    with pytest.raises(AudioFormatError, match=r"empty\.wav: the file holds no samples"):
        load_audio(tmp_path / "empty.wav")


def test_silent_audio_keeps_the_transcripts_segments_without_f0_peaks():
    from convsynth_jax.annotate.audio import annotate_audio
    from convsynth_jax.annotate.params import AnnotateParams
    from convsynth_jax.io.audio import Audio

    words = pd.DataFrame({"start": [0.1, 0.5], "end": [0.4, 0.9], "word": ["hello", "there"]})
    seg = annotate_audio(words, Audio(np.zeros(16000, np.float32), 16000, "silent.wav"), AnnotateParams())
    assert list(seg["kind"]) == ["PC"] and seg["f0_peak"].isna().all()


def test_single_frame_clip_loads_and_has_no_motion():
    from convsynth_jax.annotate.motion import joint_speeds
    from convsynth_jax.annotate.params import AnnotateParams
    from convsynth_jax.io.bvh import load_bvh

    clip = load_bvh(Path(__file__).parent / "data" / "dataset-2_run_normal_047_f68-88.bvh").slice(0, 1)
    speeds = joint_speeds(clip, AnnotateParams())
    assert {k: v.tolist() for k, v in speeds.items()} == {"LH": [0.0], "RH": [0.0], "Nod": [0.0]}
