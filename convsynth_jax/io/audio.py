"""Audio: WAV (mono or stereo, any sample rate, 8/16/24/32-bit integer or float samples) read by SciPy;
FLAC, OGG/Vorbis, MP3, AIFF and the other formats of libsndfile (the ``soundfile`` package, which
librosa brings) read by libsndfile, as is a WAV that SciPy cannot read (e.g. A-law or ADPCM)."""
from __future__ import annotations

import wave
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.io import wavfile

from ..errors import AudioFormatError, MissingFileError
from ..utils import atomic_path


@dataclass(frozen=True)
class Audio:
    """samples: float32 (N,) mono or (N, C) multichannel in [-1, 1]; sample_rate in Hz."""

    samples: np.ndarray
    sample_rate: int
    path: str = ""

    @property
    def num_channels(self) -> int:
        return 1 if self.samples.ndim == 1 else int(self.samples.shape[1])

    @property
    def num_samples(self) -> int:
        return int(self.samples.shape[0])

    @property
    def duration(self) -> float:
        return self.num_samples / float(self.sample_rate)

    def channel(self, i: int) -> "Audio":
        if self.samples.ndim == 1:
            if i != 0:
                raise AudioFormatError(f"mono audio has no channel {i}", self.path)
            return self
        if not 0 <= i < self.num_channels:
            raise AudioFormatError(f"channel {i} requested, file has {self.num_channels}", self.path)
        return Audio(np.ascontiguousarray(self.samples[:, i]), self.sample_rate, self.path)


def wav_duration(path: str | Path) -> float:
    """Duration from the WAV header alone (cheap); falls back to a full read for float WAVs."""
    path = Path(path)
    try:
        with wave.open(str(path), "rb") as w:
            return w.getnframes() / float(w.getframerate())
    except OSError as e:
        raise AudioFormatError(f"cannot read WAV header ({e})", path) from None
    except Exception:  # noqa: BLE001 - wave.Error, EOFError, or a crash of the wave module on a damaged header:
        return load_audio(path).duration  # the full reader says what is wrong


def _read_libsndfile(path: Path, scipy_error: Exception | None = None) -> tuple[int, np.ndarray]:
    """(rate, float32 samples) through libsndfile; its refusal names the file (and SciPy's, for a WAV)."""
    import soundfile

    try:
        data, rate = soundfile.read(str(path), dtype="float32", always_2d=False)
    except (RuntimeError, TypeError, ValueError, OSError) as e:  # soundfile.LibsndfileError is a RuntimeError
        why = f"SciPy: {scipy_error}; libsndfile: {e}" if scipy_error is not None else f"{e}"
        raise AudioFormatError(f"unreadable audio ({why})", path) from None
    return int(rate), data


def load_audio(path: str | Path, channel: int | None = None) -> Audio:
    path = Path(path)
    if not path.is_file():
        raise MissingFileError("audio file not found", path)
    if path.suffix.lower() not in (".wav", ".wave"):
        rate, data = _read_libsndfile(path)
    else:
        try:
            rate, data = wavfile.read(path)
        except (ValueError, EOFError, OSError) as e:
            rate, data = _read_libsndfile(path, e)
        except Exception as e:  # noqa: BLE001 - scipy's reader crashes on some damaged headers (RuntimeError, UnboundLocalError)
            raise AudioFormatError(f"unreadable WAV (damaged header: {type(e).__name__} {e})", path) from None
    if data.size == 0:
        raise AudioFormatError("the file holds no samples", path)
    if data.dtype == np.uint8:
        x = (data.astype(np.float32) - 128.0) / 128.0
    elif np.issubdtype(data.dtype, np.integer):
        x = data.astype(np.float32) / float(np.iinfo(data.dtype).max)
    else:
        x = data.astype(np.float32)
    if not np.all(np.isfinite(x)):
        bad = int(np.argwhere(~np.isfinite(x.reshape(len(x), -1)))[0, 0])
        raise AudioFormatError(f"non-finite sample at sample {bad} ({bad / rate:.3f} s)", path, f"sample {bad}")
    audio = Audio(x, int(rate), str(path))
    return audio.channel(channel) if channel is not None else audio


def save_wav(path: str | Path, samples: np.ndarray, sample_rate: int) -> Path:
    """Write 16-bit PCM (clipped to [-1, 1]) atomically."""
    path = Path(path)
    x = np.asarray(samples, dtype=np.float64)
    if not np.all(np.isfinite(x)):
        raise AudioFormatError("refusing to write non-finite samples", path)
    pcm = np.round(np.clip(x, -1.0, 1.0) * 32767).astype(np.int16)
    with atomic_path(path, suffix=".wav") as tmp:
        wavfile.write(tmp, int(sample_rate), pcm)
    return path
