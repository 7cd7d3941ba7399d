"""The BEAT2 layout (PantoMatrix): ``smplxflame_30/<take>.npz`` (SMPL-X parameters),
``wave16k/<take>.wav`` (16 kHz audio) and ``textgrid/<take>.TextGrid`` (word alignments), take
names ``<speaker id>_<speaker name>_<...>`` (e.g. ``2_scott_0_1_1``).

BEAT2 is not dyadic: every take is one speaker. ``pairing="pseudo_dyad"`` (the only pairing, named
so that nobody mistakes it for a conversation) makes sessions for the dyadic pipeline from unrelated
recordings: takes in name order are paired two by two (``main-agent``, ``interloctr``); a take left
over (one take, or an odd count) is paired with a copy of itself shifted in time (motion, audio and
words rotated together by ``shift_s``, default half the take, so the copy is one coherent recording
whose speech has nothing to do with the original's at any moment). The copy is written once into
``derived_dir`` (tasks: ``${cache_dir}/beat2_pseudo_dyads``; motion ``.npz``, audio ``.wav``,
words ``.tsv``) and named ``<take>_shifted<frames>``;
its character is ``<speaker>_shifted`` so a speaker's motion graph never holds a rotated duplicate
of its own take. Any statistic relating a participant to its partner is then a **null control**:
``Corpus.metadata["pairing"]`` says so and tasks report it.

Motion is SMPL-X, read by :mod:`convsynth_jax.io.smplx`: exact rest joints from ``smplx_model``
(the user's SMPL-X model file) when given, else the approximate template skeleton.
"""
from __future__ import annotations

import hashlib
import re
import tempfile
from pathlib import Path

import numpy as np

from ..errors import ConfigError, CorpusError, MissingFileError
from ..utils import atomic_path

PAIRINGS = ("pseudo_dyad",)
TAKE_PATTERN = re.compile(r"^(?P<speaker_id>\d+)_(?P<speaker>[A-Za-z]+)_.+$")
NULL_CONTROL = ("pseudo_dyad: BEAT2 takes are monologues; partners are unrelated takes or time-shifted copies, "
                "so partner statistics are a null control")


def _shifted_copy(take: str, npz: Path, wav: Path, words_path: Path, shift_s: float | None, out_root: Path):
    """(npz, wav, tsv, shift in frames) of the take rotated in time, written once under ``out_root``."""
    from .audio import load_audio, save_wav
    from .smplx import load_smplx_take
    from .transcripts import load_transcript, save_transcript_tsv

    t = load_smplx_take(npz)
    shift = int(round((t.duration / 2 if shift_s is None else float(shift_s)) * t.fps)) % t.num_frames
    if shift == 0:
        raise ConfigError(f"corpus.pseudo_shift_s={shift_s} shifts take {take!r} by 0 frames (a copy identical "
                          "to the take)", where="corpus.pseudo_shift_s")
    name = f"{take}_shifted{shift}"
    st = [f.stat() for f in (npz, wav, words_path)]
    stamp = "_".join(f"{s.st_size}-{s.st_mtime_ns}" for s in st)
    folder = out_root / f"{name}_{hashlib.sha1(stamp.encode()).hexdigest()[:10]}"
    paths = folder / f"{name}.npz", folder / f"{name}.wav", folder / f"{name}.tsv"
    if all(p.is_file() for p in paths):
        return (*paths, shift, name)
    dur = t.num_frames / t.fps
    with atomic_path(paths[0], suffix=".npz") as tmp:
        with open(tmp, "wb") as fh:
            np.savez(fh, poses=np.roll(t.poses.reshape(t.num_frames, -1), -shift, axis=0),
                     trans=np.roll(t.trans, -shift, axis=0), betas=t.betas, mocap_frame_rate=np.float64(t.fps))
    audio = load_audio(wav)
    x = audio.samples if audio.samples.ndim == 1 else audio.samples[:, 0]
    save_wav(paths[1], np.roll(x, -int(round(shift / t.fps * audio.sample_rate))), audio.sample_rate)
    words = load_transcript(words_path).copy()
    sec = shift / t.fps
    start, end = words["start"] - sec, words["end"] - sec
    wrap = end <= 0
    start, end = start.where(~wrap, start + dur), end.where(~wrap, end + dur)
    words["start"], words["end"] = start, end
    words = words[words["start"] >= 0].sort_values("start")   # a word cut by the seam is dropped
    save_transcript_tsv(words, paths[2])
    return (*paths, shift, name)


def load_beat2(root: str | Path, pairing: str = "pseudo_dyad", shift_s: float | None = None,
               smplx_model: str | Path | None = None, characters: dict | None = None,
               derived_dir: str | Path | None = None, tolerance: float = 1.0, check: bool = True):
    """A BEAT2 folder as a corpus of pseudo-dyads (module docstring). ``characters`` (role ->
    character name) renames the characters of the roles it names (default: the speaker names)."""
    from .corpus import Corpus, Participant, Session, check_durations

    root = Path(root)
    if pairing not in PAIRINGS:
        raise ConfigError(f"corpus.pairing={pairing!r}: BEAT2 is single-speaker; the pairing is one of "
                          f"{list(PAIRINGS)}", where="corpus.pairing")
    if not root.is_dir():
        raise MissingFileError("BEAT2 folder not found", root)
    motion_dir = root / "smplxflame_30"
    if not motion_dir.is_dir():
        raise MissingFileError("no smplxflame_30/ folder (BEAT2 layout: smplxflame_30/, wave16k/, textgrid/)", motion_dir)
    takes = sorted(motion_dir.glob("*.npz"))
    if not takes:
        raise CorpusError("no <take>.npz files (BEAT2 layout)", motion_dir)
    characters = {str(k): str(v) for k, v in (characters or {}).items()}
    # the data folder may be read-only: the copies go to the caller's folder, else the temporary one
    derived = (Path(derived_dir) if derived_dir is not None
               else Path(tempfile.gettempdir()) / "convsynth_beat2_pseudo_dyads")
    entries = []
    for npz in takes:
        m = TAKE_PATTERN.match(npz.stem)
        if m is None:
            raise CorpusError("take name is not <speaker id>_<speaker name>_<...> (BEAT2 naming)", npz)
        wav = root / "wave16k" / f"{npz.stem}.wav"
        words = root / "textgrid" / f"{npz.stem}.TextGrid"
        for f, what in ((wav, "audio"), (words, "word alignment")):
            if not f.is_file():
                raise MissingFileError(f"take {npz.stem!r} has no {what}", f)
        entries.append((npz.stem, m.group("speaker"), npz, wav, words))
    sessions = []
    roles = ("main-agent", "interloctr")

    def part(role, speaker, npz, wav, words, session, listed=None):
        return Participant(role, characters.get(role, speaker), npz, wav, words, None, session,
                           listed_in=listed, smplx_model=Path(smplx_model) if smplx_model else None)

    for k in range(0, len(entries), 2):
        a = entries[k]
        if k + 1 < len(entries):
            b = entries[k + 1]
            name = f"{a[0]}+{b[0]}"
            sessions.append(Session(name, (part(roles[0], *a[1:], name), part(roles[1], *b[1:], name))))
        else:
            npz, wav, tsv, shift, copy = _shifted_copy(a[0], a[2], a[3], a[4], shift_s, derived)
            name = f"{a[0]}+{copy}"
            sessions.append(Session(name, (part(roles[0], *a[1:], name),
                                           part(roles[1], f"{a[1]}_shifted", npz, wav, tsv, name))))
    corpus = Corpus(root, sessions, {"layout": "beat2", "pairing": "pseudo_dyad", "partner_statistics": "null control",
                                     "note": NULL_CONTROL})
    if check:
        for s in sessions:
            for p in s.participants:
                check_durations(p, tolerance)
    return corpus
