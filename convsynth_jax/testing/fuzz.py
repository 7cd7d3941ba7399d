"""Fuzzing the readers (tests/test_fuzz_readers.py, experiments/bench/fuzz_readers.py).

Each reader has a small valid seed written by :func:`write_seeds` and a function that reads a file
of its kind. A case mutates one file of a seed (bytes cut, flipped, inserted, a line deleted or
repeated, a number replaced by NaN, inf, a huge value, a negative value or text) and runs the
reader. :func:`check_case` classifies the outcome:

* ``loaded``: the reader returned (the mutation left a valid file);
* ``project_error``: it raised the project's error (:class:`convsynth_jax.errors.ConvSynthError`)
  and the message names the mutated file (or, for a corpus, the manifest or folder);
* ``unnamed_error``: the project's error without the file's name (a defect);
* ``unexpected``: any other exception (a defect);
* ``slow``: it took longer than ``HANG_S`` (a defect).

Test helper only: no library module imports it.
"""
from __future__ import annotations

import re
import shutil
import time
import traceback
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

HANG_S = 5.0

TSV = "0.10\t0.40\thello\n0.45\t0.80\tthere\n1.20\t1.50\tyeah\n"
CSV = "start,end,word\n0.10,0.40,hello\n0.45,0.80,there\n1.20,1.50,yeah\n"
IBM_JSON = """{"results": [
  {"alternatives": [{"transcript": "so %HESITATION we went ",
    "timestamps": [["so", 0.1, 0.3], ["%HESITATION", 0.35, 0.8], ["we", 0.9, 1.0], ["went", 1.0, 1.3]]}], "final": true},
  {"alternatives": [{"transcript": "yeah ", "timestamps": [["yeah", 1.4, 1.6]]}], "final": true}
]}
"""
# the TextGrid seed (written by io.transcripts.save_textgrid): a leading gap and a word with quotes
TEXTGRID_WORDS = ((0.5, 0.9, "well"), (0.9, 1.8, 'I said "hi"'))
TEXTGRID_SECONDS = 1.8
MANIFEST_YAML = """sessions:
  - name: s1
    participants:
      - {role: main-agent, character: A, motion: a.bvh, audio: a.wav, transcript: a.tsv}
      - {role: interloctr, character: B, motion: b.bvh, audio: b.wav, transcript: b.tsv}
"""
MANIFEST_CSV = """session,role,character,motion,audio,transcript
s1,main-agent,A,a.bvh,a.wav,a.tsv
s1,interloctr,B,b.bvh,b.wav,b.tsv
"""


def _motion(frames: int = 60):
    from ..skeleton import Motion, Skeleton

    chans = ("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")
    rot3 = ("Zrotation", "Xrotation", "Yrotation")
    skel = Skeleton(("Hips", "Spine", "Head"), (-1, 0, 1), np.array([[0, 90, 0], [0, 10, 0], [0, 20, 0]], float),
                    (chans, rot3, rot3), ((2, (0.0, 5.0, 0.0)),))
    t = np.linspace(0, 1, frames)
    rot = np.zeros((frames, 3, 4))
    rot[..., 0] = np.cos(0.1 * t)[:, None]
    rot[..., 2] = np.sin(0.1 * t)[:, None]
    trans = np.broadcast_to(skel.offsets, (frames, 3, 3)).copy()
    trans[:, 0, 0] = np.linspace(0, 5, frames)
    return Motion(skel, rot, trans, 30.0)


def write_seeds(root: Path) -> dict[str, Path]:
    """Valid seed files under ``root``: reader name -> the file (or folder) its reader opens."""
    import pandas as pd

    from ..io.audio import save_wav
    from ..io.bvh import save_bvh
    from ..io.transcripts import COLUMNS, save_textgrid

    root.mkdir(parents=True, exist_ok=True)
    m = _motion()
    wav = 0.1 * np.sin(2 * np.pi * 220 * np.arange(16000) / 8000.0)  # 2 s at 8 kHz, as long as the motion
    (root / "words.tsv").write_text(TSV)
    (root / "words.csv").write_text(CSV)
    (root / "words.json").write_text(IBM_JSON)
    save_textgrid(pd.DataFrame(TEXTGRID_WORDS, columns=COLUMNS), root / "words.TextGrid", TEXTGRID_SECONDS)
    save_bvh(m, root / "clip.bvh", precision=4)
    save_wav(root / "clip.wav", wav, 8000)
    man = root / "manifest"
    man.mkdir(exist_ok=True)
    genea = root / "genea"
    genea.mkdir(exist_ok=True)
    for folder, names in ((man, ("a", "b")), (genea, ("s1_main-agent", "s1_interloctr"))):
        for n in names:
            save_bvh(m, folder / f"{n}.bvh", precision=4)
            save_wav(folder / f"{n}.wav", wav, 8000)
            (folder / f"{n}.tsv").write_text(TSV)
    (man / "corpus.yaml").write_text(MANIFEST_YAML)
    (man / "corpus.csv").write_text(MANIFEST_CSV)
    return {"bvh": root / "clip.bvh", "wav": root / "clip.wav", "textgrid": root / "words.TextGrid",
            "tsv": root / "words.tsv", "csv": root / "words.csv", "ibm_json": root / "words.json",
            "manifest_yaml": man / "corpus.yaml", "manifest_csv": man / "corpus.csv", "genea": genea}


def _read_bvh(p: Path):
    from ..io.bvh import load_bvh

    return load_bvh(p)


def _read_wav(p: Path):
    from ..io.audio import load_audio

    return load_audio(p)


def _read_transcript(p: Path):
    from ..io.transcripts import load_transcript

    return load_transcript(p)


def _read_corpus(p: Path):
    from ..io.corpus import load_corpus

    c = load_corpus(p, layout="genea" if p.is_dir() else "manifest")
    for s in c.sessions:  # a corpus reader is done when every file of it has been read
        for part in s.participants:
            part.load_motion()
            part.load_audio()
            part.load_transcript()
    return c


READERS: dict[str, Callable[[Path], object]] = {
    "bvh": _read_bvh, "wav": _read_wav, "textgrid": _read_transcript, "tsv": _read_transcript,
    "csv": _read_transcript, "ibm_json": _read_transcript, "manifest_yaml": _read_corpus,
    "manifest_csv": _read_corpus, "genea": _read_corpus,
}

# replacements for a numeric token: the numerical faults real files come with
NUMBERS = (b"nan", b"NaN", b"inf", b"-inf", b"1e309", b"-1", b"0", b"1e12", b"x", b"", b"--", b"1.5.2")
NUMBER = re.compile(rb"-?\d+(\.\d+)?(e-?\d+)?")


@dataclass(frozen=True)
class Mutation:
    """One change to a file's bytes. kind: cut | flip | flip_head (in the first 64 bytes) | insert | delete_line | repeat_line | number |
    pos, arg: where and what (interpreted modulo sizes)."""

    kind: str
    pos: int
    arg: int

    def apply(self, data: bytes) -> bytes:
        n = len(data)
        if self.kind == "cut":
            return data[: self.pos % (n + 1)]
        if self.kind in ("flip", "flip_head") and n:
            i = self.pos % (min(n, 64) if self.kind == "flip_head" else n)
            return data[:i] + bytes([data[i] ^ (1 + self.arg % 255)]) + data[i + 1:]
        if self.kind == "insert":
            i = self.pos % (n + 1)
            return data[:i] + bytes([self.arg % 256]) * (1 + self.arg % 7) + data[i:]
        lines = data.split(b"\n")
        if self.kind == "delete_line":
            i = self.pos % len(lines)
            return b"\n".join(lines[:i] + lines[i + 1:])
        if self.kind == "repeat_line":
            i = self.pos % len(lines)
            return b"\n".join(lines[:i + 1] + [lines[i]] * (1 + self.arg % 3) + lines[i + 1:])
        if self.kind == "number":
            spans = [m.span() for m in NUMBER.finditer(data)]
            if not spans:
                return data
            a, b = spans[self.pos % len(spans)]
            return data[:a] + NUMBERS[self.arg % len(NUMBERS)] + data[b:]
        return data


KINDS = ("cut", "flip", "flip_head", "insert", "delete_line", "repeat_line", "number")


def corpus_files(target: Path) -> list[Path]:
    """The files a corpus case may mutate (sorted): every file of the folder."""
    folder = target if target.is_dir() else target.parent
    return sorted(p for p in folder.iterdir() if p.is_file())


@dataclass(frozen=True)
class Outcome:
    status: str          # loaded | project_error | unnamed_error | unexpected | slow
    seconds: float
    detail: str = ""


def run_case(reader: str, seed_root: Path, work: Path, mutations: list[Mutation], file_index: int = 0,
             remove: bool = False) -> Outcome:
    """Copy the seed of ``reader`` into ``work`` (emptied first), apply ``mutations`` to one of its files
    (corpora: file ``file_index`` of the folder; ``remove``: delete it instead) and read it."""
    seeds = _seed_paths(seed_root)
    src = seeds[reader]
    if work.exists():
        shutil.rmtree(work)
    if src.is_dir() or reader.startswith("manifest"):
        shutil.copytree(src if src.is_dir() else src.parent, work)
        target = work if src.is_dir() else work / src.name
        files = corpus_files(target)
        victim = files[file_index % len(files)]
    else:
        work.mkdir(parents=True)
        target = victim = work / src.name
        shutil.copy2(src, victim)
    if remove and victim != target:
        victim.unlink()
    else:
        data = victim.read_bytes()
        for m in mutations:
            data = m.apply(data)
        victim.write_bytes(data)
    return check_case(READERS[reader], target, {victim.name, target.name})


def check_case(read: Callable[[Path], object], target: Path, names: set[str]) -> Outcome:
    from ..errors import ConvSynthError

    t0 = time.perf_counter()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # e.g. scipy's WavFileWarning on a truncated WAV (still loaded)
            read(target)
        status, detail = "loaded", ""
    except ConvSynthError as e:
        msg = str(e)
        status = "project_error" if any(n in msg for n in names) or target.name in msg else "unnamed_error"
        detail = f"{type(e).__name__}: {msg}"
    except Exception as e:  # noqa: BLE001 - classified: this is what the fuzzing looks for
        status, detail = "unexpected", "".join(traceback.format_exception_only(type(e), e)).strip()
    seconds = time.perf_counter() - t0
    if seconds > HANG_S:
        status = "slow"
    return Outcome(status, seconds, detail)


_SEEDS: dict[Path, dict] = {}


def _seed_paths(root: Path) -> dict:
    if root not in _SEEDS:
        _SEEDS[root] = write_seeds(root)
    return _SEEDS[root]
