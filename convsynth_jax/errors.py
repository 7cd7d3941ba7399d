"""One exception hierarchy for every input problem the library can report.

Every error names the file and the place (line, frame, word, channel) and says what was expected,
so a researcher pointed at a broken recording can fix it without a debugger.
"""
from __future__ import annotations

from pathlib import Path


class ConvSynthError(Exception):
    """Base class of all errors raised deliberately by convsynth_jax."""

    def __init__(self, message: str, path: str | Path | None = None, where: str | None = None):
        self.path = None if path is None else str(path)
        self.where = where
        self.reason = message
        parts = []
        if self.path is not None:
            parts.append(self.path)
        if where:
            parts.append(where)
        prefix = ": ".join(parts)
        super().__init__(f"{prefix}: {message}" if prefix else message)


class FormatError(ConvSynthError):
    """A file exists but its contents are malformed (truncated, non-numeric, wrong counts)."""


class BVHFormatError(FormatError):
    """A BVH file is malformed."""


class TranscriptFormatError(FormatError):
    """A transcript (TextGrid, TSV/CSV, IBM JSON) is malformed or inconsistent."""


class AudioFormatError(FormatError):
    """A WAV file cannot be read or holds unusable samples."""


class MissingFileError(ConvSynthError, FileNotFoundError):
    """A file the corpus layout or the configuration requires does not exist."""


class CorpusError(ConvSynthError):
    """A corpus is inconsistent: missing participants, mismatched durations, bad manifest."""


class WriteError(ConvSynthError, OSError):
    """A result cannot be written (read-only folder, full disk, quota). Nothing half-written is left:
    the temporary file is removed and the target keeps its previous contents (or stays absent)."""


class LabelError(ConvSynthError):
    """An unknown label (audio segment kind, motion event kind, hypothesis) was given."""


class ConfigError(ConvSynthError):
    """A configuration value is invalid."""


class GraphError(ConvSynthError):
    """A motion graph cannot be built or loaded."""


class SearchFailure(ConvSynthError):
    """A search found no path; raised only when the caller asks for an exception."""


class CDBNError(ConvSynthError):
    """The constrained DBN cannot be trained or applied: bad features, constraints or model files."""


class WalkTalkError(ConvSynthError):
    """Walk-the-talk input problem: a gesture clip that travels, a locomotion clip with too few
    gait cycles, mismatched skeletons, gesture phases out of order, utterance times outside the
    timeline, invalid stylization/gaze parameters, a character addressing itself."""
