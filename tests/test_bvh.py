
import numpy as np
import pytest

from convsynth_jax.errors import BVHFormatError, ConvSynthError, MissingFileError
from convsynth_jax.io import load_bvh, save_bvh
from convsynth_jax.kinematics import forward_kinematics
from tolerances import ROUND_TRIP

HAND = """HIERARCHY
ROOT Pelvis
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Yrotation Xrotation Zrotation
  JOINT Chest
  {
    OFFSET 0 10 0
    CHANNELS 3 Xrotation Yrotation Zrotation
    JOINT Head
    {
      OFFSET 0 8 1
      CHANNELS 3 Yrotation Xrotation Zrotation
      End Site
      {
        OFFSET 0 5 0
      }
    }
  }
  JOINT Leg
  {
    OFFSET 5 -2 0
    CHANNELS 3 Zrotation Yrotation Xrotation
    End Site
    {
      OFFSET 0 -40 0
    }
  }
}
MOTION
Frames: 3
Frame Time: 0.0166667
1 90 2 10 20 30 5 -5 15 40 0 10 0 0 -90
1.5 90 2 11 21 31 6 -4 16 41 1 11 1 1 -80
2 91 2 12 22 32 7 -3 17 42 2 12 2 2 -70
"""


def write(tmp_path, text, name="x.bvh"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_hand_written_any_order_and_end_sites_round_trip(tmp_path):
    m = load_bvh(write(tmp_path, HAND))
    assert m.num_frames == 3 and m.fps == 60.0
    assert m.skeleton.names == ("Pelvis", "Chest", "Head", "Leg")
    assert len(m.skeleton.end_sites) == 2
    pos = np.asarray(forward_kinematics(m))
    # frame 0 root position is the channel values
    np.testing.assert_allclose(pos[0, 0], [1, 90, 2], atol=1e-5)
    out = save_bvh(m, tmp_path / "y.bvh")
    m2 = load_bvh(out)
    assert m2.skeleton.channels == m.skeleton.channels
    np.testing.assert_allclose(np.asarray(forward_kinematics(m2)), pos, atol=ROUND_TRIP)
    assert "End Site" in out.read_text()


def test_resample_60_to_30_and_back(tmp_path):
    m = load_bvh(write(tmp_path, HAND))
    m30 = m.resample(30)
    assert m30.num_frames == 2 and m30.fps == 30
    np.testing.assert_allclose(m30.rotations[1], m.rotations[2], atol=1e-6)
    m120 = m.resample(120)
    assert m120.num_frames == 5
    # the midpoint of frames 0 and 1 is their slerp
    from convsynth_jax.rotations import quat_slerp

    np.testing.assert_allclose(m120.rotations[1], quat_slerp(m.rotations[0], m.rotations[1], 0.5), atol=1e-6)
    m_load = load_bvh(write(tmp_path, HAND), fps=30)
    assert m_load.num_frames == 2


def _bad(tmp_path, text):
    with pytest.raises(BVHFormatError) as e:
        load_bvh(write(tmp_path, text, "bad.bvh"))
    assert "bad.bvh" in str(e.value)
    return str(e.value)


def test_truncated(tmp_path):
    msg = _bad(tmp_path, HAND.rsplit("\n", 2)[0] + "\n")
    assert "truncated" in msg and "line" in msg


def test_wrong_channel_count(tmp_path):
    lines = HAND.splitlines()
    lines[-2] = lines[-2] + " 7"
    msg = _bad(tmp_path, "\n".join(lines) + "\n")
    assert "frame 1" in msg and "16 values, expected 15" in msg and "line 34" in msg


def test_non_numeric_and_nan(tmp_path):
    msg = _bad(tmp_path, HAND.replace("1.5 90 2", "1.5 abc 2"))
    assert "non-numeric" in msg and "'abc'" in msg and "frame 1" in msg
    msg = _bad(tmp_path, HAND.replace("1.5 90 2", "1.5 nan 2"))
    assert "non-finite" in msg and "frame 1" in msg


def test_missing_motion_and_zero_frames(tmp_path):
    assert "MOTION" in _bad(tmp_path, HAND.split("MOTION")[0])
    assert "zero frames" in _bad(tmp_path, HAND.replace("Frames: 3", "Frames: 0"))


def test_bad_channels_and_structure(tmp_path):
    assert "CHANNELS says 3" in _bad(tmp_path, HAND.replace("CHANNELS 3 Xrotation Yrotation Zrotation", "CHANNELS 3 Xrotation Yrotation"))
    assert "unknown channel" in _bad(tmp_path, HAND.replace("Zrotation Yrotation Xrotation", "Zrotation Yrotation Wrotation"))
    assert "HIERARCHY" in _bad(tmp_path, "hello\n")


def test_missing_file(tmp_path):
    with pytest.raises(MissingFileError):
        load_bvh(tmp_path / "nope.bvh")


def test_bvh_files_of_a_file_or_a_folder(tmp_path):
    from convsynth_jax.io.bvh import bvh_files

    upper, lower = write(tmp_path, HAND, "A.BVH"), write(tmp_path, HAND, "b.bvh")
    write(tmp_path, "not motion", "notes.txt")
    (tmp_path / "sub.bvh").mkdir()                                   # a folder named like a file is skipped
    assert bvh_files(tmp_path) == [upper, lower]                     # sorted, any case of the suffix
    assert bvh_files(str(lower)) == [lower]
    for bad, why in ((tmp_path / "missing.bvh", "no such"), (tmp_path / "notes.txt", "not a .bvh"),
                     (tmp_path / "sub.bvh", "holds no .bvh")):
        with pytest.raises(MissingFileError, match=why):
            bvh_files(bad)


def test_failed_write_leaves_nothing(tmp_path):
    m = load_bvh(write(tmp_path, HAND))
    rot = m.rotations.copy()
    rot[1, 1] = np.nan
    import dataclasses

    with pytest.raises(ConvSynthError):
        save_bvh(dataclasses.replace(m, rotations=rot), tmp_path / "out.bvh")
    assert not (tmp_path / "out.bvh").exists()
    assert [p.name for p in tmp_path.iterdir()] == ["x.bvh"]


def test_vendored_fixtures_round_trip(tmp_path):
    from conftest import TEST_DATA

    files = sorted(TEST_DATA.glob("*.bvh"))
    assert files, "vendored BVH fixtures missing"
    for f in files:
        m = load_bvh(f)
        pos = np.asarray(forward_kinematics(m))
        m2 = load_bvh(save_bvh(m, tmp_path / f.name))
        np.testing.assert_allclose(np.asarray(forward_kinematics(m2)), pos, atol=ROUND_TRIP)


def _fk_padded(m, size=1024):
    """FK with the frame axis padded to a fixed size (one compile for every clip)."""
    import jax.numpy as jnp

    from convsynth_jax.kinematics import fk_kernel

    pad = size - m.num_frames
    rot = np.concatenate([m.rotations, np.repeat(m.rotations[-1:], pad, 0)])
    tr = np.concatenate([m.translations, np.repeat(m.translations[-1:], pad, 0)])
    return np.asarray(fk_kernel(jnp.asarray(rot, jnp.float32), jnp.asarray(tr, jnp.float32), m.skeleton.parents)[0])[: m.num_frames]


def test_every_shared_bandai_file_loads_and_round_trips(bandai_dir, tmp_path):
    files = sorted(bandai_dir.glob("*.bvh"))
    assert len(files) == 465
    total = 0
    for k, f in enumerate(files):
        m = load_bvh(f)
        total += m.num_frames
        assert m.fps == 30 and m.skeleton.num_joints == 22
        if k % 5 == 0 and m.num_frames <= 1024:  # the round trip on a spread of files
            m2 = load_bvh(save_bvh(m, tmp_path / "rt.bvh"))
            np.testing.assert_allclose(_fk_padded(m2), _fk_padded(m), atol=ROUND_TRIP)
    assert total == 54067
