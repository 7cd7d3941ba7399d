import shutil

import numpy as np
import pytest
import yaml
from scipy.io import wavfile

from convsynth_jax.errors import AudioFormatError, CorpusError, MissingFileError
from convsynth_jax.io import load_audio, load_corpus, save_wav


def test_wav_mono_stereo_and_rates(tmp_path):
    x = np.sin(np.linspace(0, 100, 8000))
    save_wav(tmp_path / "m.wav", x, 8000)
    a = load_audio(tmp_path / "m.wav")
    assert a.sample_rate == 8000 and a.num_channels == 1 and abs(a.duration - 1.0) < 1e-9
    np.testing.assert_allclose(a.samples, x, atol=1e-4)
    st = np.stack([x, -x], 1).astype(np.float32)
    wavfile.write(tmp_path / "s.wav", 44100, st)
    b = load_audio(tmp_path / "s.wav")
    assert b.num_channels == 2 and b.sample_rate == 44100
    np.testing.assert_allclose(load_audio(tmp_path / "s.wav", channel=1).samples, -x, atol=1e-6)
    with pytest.raises(AudioFormatError, match="channel 2"):
        b.channel(2)


def test_unreadable_and_nan_wav(tmp_path):
    (tmp_path / "bad.wav").write_bytes(b"RIFF\x00\x00not a wav")
    with pytest.raises(AudioFormatError, match="bad.wav"):
        load_audio(tmp_path / "bad.wav")
    wavfile.write(tmp_path / "nan.wav", 100, np.array([0.0, np.nan, 0.1], np.float32))
    with pytest.raises(AudioFormatError, match="sample 1"):
        load_audio(tmp_path / "nan.wav")
    with pytest.raises(MissingFileError):
        load_audio(tmp_path / "none.wav")


def test_flac_ogg_and_mu_law_wav_are_read_through_libsndfile(tmp_path):
    """A user's speech often comes as FLAC or OGG, or as a telephone-style WAV that SciPy cannot read:
    each is read (libsndfile), with its rate and channels, and a damaged file names itself."""
    import soundfile

    rate = 22050
    x = 0.5 * np.sin(np.linspace(0, 300, rate)).astype(np.float32)
    st = np.stack([x, -x], 1)
    soundfile.write(tmp_path / "s.flac", st, rate, subtype="PCM_16")
    a = load_audio(tmp_path / "s.flac")
    assert a.sample_rate == rate and a.num_channels == 2 and abs(a.duration - 1.0) < 1e-9
    np.testing.assert_allclose(load_audio(tmp_path / "s.flac", channel=1).samples, -x, atol=1e-4)
    soundfile.write(tmp_path / "m.ogg", x, rate, format="OGG", subtype="VORBIS")
    b = load_audio(tmp_path / "m.ogg")
    assert b.sample_rate == rate and b.num_channels == 1 and abs(b.duration - 1.0) < 0.01
    assert np.corrcoef(b.samples[:len(x)], x[:len(b.samples)])[0, 1] > 0.9      # lossy, but the same signal
    soundfile.write(tmp_path / "ulaw.wav", x, 8000, subtype="ULAW")
    with pytest.raises(ValueError):                       # what SciPy alone would say
        wavfile.read(tmp_path / "ulaw.wav")
    c = load_audio(tmp_path / "ulaw.wav")
    assert c.sample_rate == 8000 and np.abs(c.samples - x).max() < 0.05
    (tmp_path / "bad.flac").write_bytes(b"fLaC not really")
    with pytest.raises(AudioFormatError, match=r"bad\.flac: unreadable audio"):
        load_audio(tmp_path / "bad.flac")


def test_genea_layout_loads(tiny_corpus_dir):
    c = load_corpus(tiny_corpus_dir)
    assert [s.name for s in c.sessions] == ["session01", "session02", "session03"]
    assert c.characters == ["female", "male"]
    p = c.sessions[0].participants[0]
    assert p.role == "main-agent" and p.character == "female"
    m = p.load_motion()
    assert m.fps == 30 and abs(m.duration - 60.0) < 0.05
    assert p.load_audio().sample_rate == 16000 and len(p.load_transcript()) > 10


def _copy(src, dst, skip=()):
    dst.mkdir()
    for f in src.iterdir():
        if f.name not in skip:
            shutil.copy(f, dst / f.name)
    return dst


def test_missing_file_and_mismatched_durations(tiny_corpus_dir, tmp_path):
    d = _copy(tiny_corpus_dir, tmp_path / "c1", skip={"session02_interloctr.tsv"})
    with pytest.raises(MissingFileError, match="session02.*interloctr transcript") as e:
        load_corpus(d)
    assert "session02_interloctr.tsv" in str(e.value)
    d2 = _copy(tiny_corpus_dir, tmp_path / "c2")
    a = load_audio(d2 / "session01_main-agent.wav")
    save_wav(d2 / "session01_main-agent.wav", a.samples[: a.sample_rate * 30], a.sample_rate)
    with pytest.raises(CorpusError, match="session01.*main-agent.*audio lasts 30.00 s"):
        load_corpus(d2)
    assert len(load_corpus(d2, tolerance=40.0).sessions) == 3


def test_stereo_session_wav_and_manifests(tiny_corpus_dir, tmp_path):
    d = _copy(tiny_corpus_dir, tmp_path / "c", skip={"session01_main-agent.wav", "session01_interloctr.wav"})
    a = load_audio(tiny_corpus_dir / "session01_main-agent.wav")
    b = load_audio(tiny_corpus_dir / "session01_interloctr.wav")
    wavfile.write(d / "session01.wav", a.sample_rate, np.stack([a.samples, b.samples], 1))
    c = load_corpus(d)
    p0, p1 = c.sessions[0].participants
    assert p0.audio_channel == 0 and p1.audio_channel == 1
    np.testing.assert_allclose(p1.load_audio().samples, b.samples, atol=1e-6)
    # YAML manifest
    man = {"sessions": [{"name": "s1", "participants": [
        {"role": "a", "character": "female", "motion": "session01_main-agent.bvh", "audio": "session01.wav",
         "audio_channel": 0, "transcript": "session01_main-agent.tsv"},
        {"role": "b", "character": "male", "motion": "session01_interloctr.bvh", "audio": "session01.wav",
         "audio_channel": 1, "transcript": "session01_interloctr.tsv"}]}]}
    (d / "m.yaml").write_text(yaml.safe_dump(man))
    cm = load_corpus(d / "m.yaml")
    assert cm.characters == ["female", "male"] and cm.sessions[0].participants[1].audio_channel == 1
    # CSV manifest with a missing file names it
    (d / "m.csv").write_text("session,role,character,motion,audio,transcript,audio_channel\n"
                             "s1,a,female,session01_main-agent.bvh,session01.wav,session01_main-agent.tsv,0\n"
                             "s1,b,male,nothere.bvh,session01.wav,session01_interloctr.tsv,1\n")
    with pytest.raises(MissingFileError, match="line 3: motion file not found"):
        load_corpus(d / "m.csv")


def test_corpus_characters_reach_every_loader(tiny_corpus_dir, tmp_path):
    """corpus.characters (role -> name) renames the roles it names, over corpus.json and manifest
    entries; the others keep their names; the configured corpus passes it to the loader."""
    from convsynth_jax.config import compose
    from convsynth_jax.tasks.common import open_corpus, params_of

    c = load_corpus(tiny_corpus_dir, characters={"main-agent": "anna"})
    assert c.characters == ["anna", "male"]
    d = _copy(tiny_corpus_dir, tmp_path / "c")
    (d / "m.csv").write_text("session,role,character,motion,audio,transcript\n"
                             "s1,a,female,session01_main-agent.bvh,session01_main-agent.wav,session01_main-agent.tsv\n"
                             "s1,b,male,session01_interloctr.bvh,session01_interloctr.wav,session01_interloctr.tsv\n")
    assert load_corpus(d / "m.csv", characters={"b": "bob"}).characters == ["bob", "female"]
    cfg = compose(["corpus=genea", f"corpus.root={tiny_corpus_dir}", "+corpus.characters.interloctr=ben"])
    assert open_corpus(params_of(cfg)).characters == ["ben", "female"]
