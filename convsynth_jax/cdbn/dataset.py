"""Turn-level datasets for the CDBN: raw features per turn, per-subject z-normalization, constraint
codes. A dataset is a list of :class:`Turn`; :func:`normalize_by_subject` returns the z-normalized
copies and the per-subject statistics."""
from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..errors import CDBNError
from .features import (
    Normalization,
    check_finite,
    check_lengths,
    head_rotation,
    read_constraints,
    speech_features,
)
from .params import CDBNFeatureParams


class Turn(NamedTuple):
    """name; subject; speech (T, 6) and motion (T, 3) (raw or z-normalized); constraints (T,) codes."""

    name: str
    subject: str
    speech: np.ndarray
    motion: np.ndarray
    constraints: np.ndarray

    def observations(self) -> np.ndarray:
        return np.concatenate([self.speech, self.motion], axis=1)


def load_turn(wav: Path, bvh: Path, constraints_tsv: Path | None, names: tuple, params: CDBNFeatureParams,
              subject: str = "", name: str = "") -> Turn:
    from ..io.audio import load_audio
    from ..io.bvh import load_bvh

    mo = load_bvh(bvh)
    if abs(mo.fps - params.fps) > 1e-6:
        mo = mo.resample(params.fps)
    m = head_rotation(mo, params)
    audio = load_audio(wav)
    n_speech = round(audio.duration * params.fps)
    n = check_lengths(np.empty(n_speech), m, wav, bvh)
    s = speech_features(audio, params, n, params.fps, path=wav)
    m = m[:n]
    check_finite(m, str(bvh), "head rotations")
    c = (read_constraints(constraints_tsv, names, n, params.fps) if constraints_tsv is not None
         else np.zeros(n, np.int32))
    return Turn(name or Path(wav).stem, subject, s, m, c)


def normalize_by_subject(turns: list[Turn]) -> tuple[list[Turn], dict]:
    """Per-subject z-normalization of both streams (Sec. IV-C). Returns (turns, {subject: (speech
    Normalization, motion Normalization)})."""
    subjects = sorted({t.subject for t in turns})
    norms = {}
    for s in subjects:
        mine = [t for t in turns if t.subject == s]
        norms[s] = (Normalization.fit(np.concatenate([t.speech for t in mine])),
                    Normalization.fit(np.concatenate([t.motion for t in mine])))
    out = [t._replace(speech=norms[t.subject][0].apply(t.speech), motion=norms[t.subject][1].apply(t.motion))
           for t in turns]
    return out, norms


def check_turns(turns: list[Turn], min_frames: int = 3) -> None:
    for t in turns:
        if len(t.speech) != len(t.motion) or len(t.constraints) != len(t.speech):
            raise CDBNError(f"turn {t.name}: {len(t.speech)} speech, {len(t.motion)} motion and "
                            f"{len(t.constraints)} constraint frames")
        check_finite(t.observations(), t.name, "features")
    if not turns:
        raise CDBNError("no turns")


def load_semisynthetic_turns(root, names: tuple, params: CDBNFeatureParams) -> list[Turn]:
    from .semisynthetic import load_semisynthetic_corpus

    return [load_turn(t["wav"], t["bvh"], t["constraints"], names, params, t["subject"], t["turn"])
            for t in load_semisynthetic_corpus(root)]
