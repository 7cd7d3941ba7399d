"""Dyadic corpus layouts: the GENEA 2023 dyadic layout and manifests (YAML or CSV).

A corpus is a list of sessions; a session has exactly two participants; a participant has motion
(BVH), audio (WAV, or one channel of a stereo session WAV) and a word-level transcript.
"""
from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from ..errors import CorpusError, FormatError, MissingFileError
from ..fingerprint import file_digest, stable_hash
from ..skeleton import Motion
from .audio import Audio, load_audio, wav_duration
from .bvh import bvh_duration  # noqa: F401  (re-exported)
from .motion import load_motion_file, motion_file_duration
from .transcripts import load_transcript

GENEA_ROLES = ("main-agent", "interloctr")
TRANSCRIPT_EXTS = (".tsv", ".csv", ".TextGrid", ".textgrid", ".json")


@dataclass(eq=False)
class Participant:
    """One person of a session. Files load lazily and are cached."""

    role: str
    character: str
    motion_path: Path
    audio_path: Path | None = None
    transcript_path: Path | None = None
    audio_channel: int | None = None
    session: str = ""
    listed_in: Path | None = None       # the manifest that lists this participant (None: a GENEA folder)
    smplx_model: Path | None = None     # an SMPL-X .npz take's model file (exact rest joints; None: template)
    _cache: dict = field(default_factory=dict, repr=False)

    def load_motion(self, fps: float | None = 30) -> Motion:
        key = ("motion", fps)
        if key not in self._cache:
            self._cache[key] = load_motion_file(self.motion_path, fps=fps, smplx_model=self.smplx_model)
        return self._cache[key]

    def load_audio(self) -> Audio:
        if self.audio_path is None:
            raise MissingFileError(f"session {self.session!r}, participant {self.role!r}: no audio file beside "
                                   f"its motion {self.motion_path.name}", self.listed_in or self.motion_path.parent)
        if "audio" not in self._cache:
            self._cache["audio"] = load_audio(self.audio_path, channel=self.audio_channel)
        return self._cache["audio"]

    def load_transcript(self) -> pd.DataFrame:
        if self.transcript_path is None:
            raise MissingFileError(f"session {self.session!r}, participant {self.role!r}: no transcript file beside "
                                   f"its motion {self.motion_path.name}", self.listed_in or self.motion_path.parent)
        if "words" not in self._cache:
            self._cache["words"] = load_transcript(self.transcript_path)
        return self._cache["words"]


@dataclass(eq=False)
class Session:
    name: str
    participants: tuple[Participant, Participant]

    def partner(self, i: int) -> Participant:
        return self.participants[1 - i]


@dataclass(eq=False)
class Corpus:
    root: Path
    sessions: list[Session]
    metadata: dict = field(default_factory=dict)

    @property
    def characters(self) -> list[str]:
        return sorted({p.character for s in self.sessions for p in s.participants})

    def fingerprint(self) -> str:
        """The hash of this corpus's content (:func:`corpus_fingerprint`)."""
        return corpus_fingerprint(self)

    def session(self, name: str) -> Session:
        for s in self.sessions:
            if s.name == name:
                return s
        raise KeyError(f"no session {name!r}; sessions are {[s.name for s in self.sessions]}")


def _file_entry(root: Path, f) -> list | None:
    """[name relative to ``root`` (else absolute), SHA-256 of its bytes or None when absent]."""
    if f is None:
        return None
    f = Path(f)
    try:
        name = str(f.resolve().relative_to(root.resolve()))
    except ValueError:
        name = str(f.resolve())
    return [name, file_digest(f)] if f.is_file() else [name, None]


def participant_fingerprint(p: Participant, root) -> list:
    """A participant's content: role, character, audio channel and the bytes of its motion, audio,
    transcript and SMPL-X model files (named relative to ``root``)."""
    root = Path(root)
    return [p.role, p.character, p.audio_channel, _file_entry(root, p.motion_path), _file_entry(root, p.audio_path),
            _file_entry(root, p.transcript_path), _file_entry(root, getattr(p, "smplx_model", None))]


def corpus_fingerprint(corpus) -> str:
    """A hash (24 hex digits) of a corpus's content: the bytes of every participant's motion, audio,
    transcript and SMPL-X model file (named relative to the corpus root), its sessions, roles,
    characters and audio channels (:func:`participant_fingerprint`), the bytes of ``corpus.json`` (for
    a synthetic corpus: the generator's configuration and version) and the layout's metadata. A file
    edited in place (names unchanged) changes it; a GENEA folder copied elsewhere keeps it. Every cache
    of results computed from a corpus is keyed by it (:mod:`convsynth_jax.fingerprint`)."""
    root = Path(corpus.root)
    meta = root / "corpus.json"
    items = [["corpus.json", file_digest(meta) if meta.is_file() else None],
             json.loads(json.dumps(corpus.metadata or {}, sort_keys=True, default=str))]
    for s in corpus.sessions:
        for p in s.participants:
            items.append([s.name, *participant_fingerprint(p, root)])
    return stable_hash(items, length=24)


def check_durations(p: Participant, tolerance: float) -> None:
    """Motion, audio and transcript durations must agree within ``tolerance`` seconds."""
    dm = motion_file_duration(p.motion_path)
    where = f"session {p.session!r}, participant {p.role!r}"
    if p.audio_path is not None:
        da = wav_duration(p.audio_path)
        if abs(da - dm) > tolerance:
            raise CorpusError(f"motion lasts {dm:.2f} s ({p.motion_path.name}) but audio lasts {da:.2f} s "
                              f"({p.audio_path.name}); tolerance {tolerance} s", p.motion_path.parent, where)
    if p.transcript_path is not None:
        words = p.load_transcript()
        if len(words):
            end = float(words["end"].max())
            if end > dm + tolerance:
                raise CorpusError(f"transcript {p.transcript_path.name} ends at {end:.2f} s, after the motion "
                                  f"({dm:.2f} s); tolerance {tolerance} s", p.motion_path.parent, where)


def _find_transcript(stem: Path) -> Path | None:
    for ext in TRANSCRIPT_EXTS:
        cand = stem.with_name(stem.name + ext)
        if cand.is_file():
            return cand
    return None


def _load_characters(root: Path) -> tuple[dict, dict]:
    meta = {}
    f = root / "corpus.json"
    if f.is_file():
        try:
            meta = json.loads(f.read_text())
        except json.JSONDecodeError as e:
            raise FormatError(f"invalid JSON ({e.msg})", f, f"line {e.lineno}") from None
    return meta, dict(meta.get("characters", {}))


def _nested_splits(root: Path) -> list[Path]:
    """The split folders of the GENEA 2023 release layout under ``root`` (``root`` itself when it is
    one): folders holding ``main-agent/bvh/``."""
    cands = [root] + sorted(d for d in root.iterdir() if d.is_dir())
    return [d for d in cands if (d / GENEA_ROLES[0] / "bvh").is_dir()]


def _genea_metadata(split: Path) -> list[dict] | None:
    """The rows of a split's ``metadata.csv`` (the release's per-take speaker ids and flags), if any."""
    f = split / "metadata.csv"
    if not f.is_file():
        return None
    try:
        return pd.read_csv(f, header=None).astype(str).values.tolist()
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as e:
        raise FormatError(f"unreadable metadata CSV ({str(e).strip()})", f) from None


def load_genea(root: str | Path, tolerance: float = 1.0, check: bool = True,
               characters: dict | None = None) -> Corpus:
    """A folder in the GENEA dyadic layout: flat (``<session>_main-agent.{bvh,wav,tsv}``,
    ``<session>_interloctr.{...}`` side by side) or the GENEA 2023 release's nested layout
    (``<split>/{main-agent,interloctr}/{bvh,wav,tsv}/<session>_<role>.<ext>``, ``root`` being the
    release folder or one split; the splits' ``metadata.csv`` go to ``Corpus.metadata``), detected
    from the files. The same files give the same sessions in either layout. ``characters`` (role ->
    character name, e.g. from ``corpus.characters``) names the characters; a role it does not name
    takes the name in the folder's ``corpus.json``, else the role itself."""
    root = Path(root)
    if not root.is_dir():
        raise MissingFileError("corpus folder not found", root)
    meta, named = _load_characters(root)
    characters = {**named, **{str(k): str(v) for k, v in (characters or {}).items()}}
    pat = re.compile(r"^(?P<session>.+)_(?P<role>main-agent|interloctr)\.bvh$")
    # session -> (folder of role -> stem without extension per kind, stereo wav or None)
    found: dict[str, tuple] = {}
    for name in sorted({m.group("session") for f in root.iterdir() if (m := pat.match(f.name))}):
        found[name] = ({r: {k: root / f"{name}_{r}" for k in ("bvh", "wav", "tsv")} for r in GENEA_ROLES},
                       root / f"{name}.wav")
    if not found:
        splits = _nested_splits(root)
        for split in splits:
            md = _genea_metadata(split)
            if md is not None:
                meta.setdefault("genea_metadata", {})[split.name] = md
            for f in sorted((split / GENEA_ROLES[0] / "bvh").iterdir()):
                m = pat.match(f.name)
                if not m or m.group("role") != GENEA_ROLES[0]:
                    continue
                name = m.group("session")
                if name in found:
                    raise CorpusError(f"session {name!r} appears in two splits", f)
                found[name] = ({r: {k: split / r / k / f"{name}_{r}" for k in ("bvh", "wav", "tsv")}
                                for r in GENEA_ROLES}, None)
    if not found:
        raise CorpusError("no <session>_main-agent.bvh / <session>_interloctr.bvh files (GENEA dyadic layout: "
                          "flat, or <split>/main-agent/bvh/ as the GENEA 2023 release)", root)
    sessions = []
    for name, (stems, stereo) in found.items():
        parts = []
        for k, role in enumerate(GENEA_ROLES):
            motion = stems[role]["bvh"].with_name(stems[role]["bvh"].name + ".bvh")
            if not motion.is_file():
                raise MissingFileError(f"session {name!r} lacks its {role} motion", motion)
            audio, channel = stems[role]["wav"].with_name(stems[role]["wav"].name + ".wav"), None
            if not audio.is_file():
                if stereo is not None and stereo.is_file():
                    audio, channel = stereo, k
                else:
                    other = f" (or a stereo {stereo.name})" if stereo is not None else ""
                    raise MissingFileError(f"session {name!r} lacks the {role} audio{other}", audio)
            transcript = _find_transcript(stems[role]["tsv"])
            if transcript is None:
                raise MissingFileError(f"session {name!r} lacks the {role} transcript",
                                       stems[role]["tsv"].with_name(stems[role]["tsv"].name + ".tsv"))
            parts.append(Participant(role, characters.get(role, role), motion, audio, transcript, channel, name))
        sessions.append(Session(name, tuple(parts)))
    corpus = Corpus(root, sessions, meta)
    if check:
        for s in sessions:
            for p in s.participants:
                check_durations(p, tolerance)
    return corpus


def _manifest_text(path: Path) -> str:
    try:
        return path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as e:
        raise FormatError(f"not UTF-8 text (byte {e.start})", path) from None


def load_manifest(path: str | Path, tolerance: float = 1.0, check: bool = True,
                  characters: dict | None = None) -> Corpus:
    """A manifest (YAML or CSV). ``characters`` (role -> character name, e.g. from
    ``corpus.characters``) renames the characters of the roles it names, over the manifest's own
    ``character`` entries; other participants keep their entry, else their role."""
    characters = {str(k): str(v) for k, v in (characters or {}).items()}
    path = Path(path)
    if not path.is_file():
        raise MissingFileError("manifest not found", path)
    base = path.parent
    if path.suffix.lower() in (".yaml", ".yml"):
        import yaml

        try:
            data = yaml.safe_load(_manifest_text(path)) or {}
        except yaml.YAMLError as e:
            raise FormatError(f"invalid YAML ({e})", path) from None
        entries = data.get("sessions") if isinstance(data, dict) else None
        if not isinstance(entries, list):
            raise FormatError("expected a top-level 'sessions' list", path)
        rows = []
        for i, s in enumerate(entries):
            if not isinstance(s, dict) or not isinstance(s.get("participants") or [], list):
                raise FormatError("expected a mapping with a 'participants' list", path, f"sessions[{i}]")
            for j, p in enumerate(s.get("participants") or []):
                if not isinstance(p, dict):
                    raise FormatError("expected a mapping (role, motion, audio, transcript)", path,
                                      f"sessions[{i}].participants[{j}]")
                rows.append({"session": s.get("name", f"session{i}"), **p, "_where": f"sessions[{i}].participants[{j}]"})
    elif path.suffix.lower() == ".csv":
        import io

        try:
            df = pd.read_csv(io.StringIO(_manifest_text(path)))
        except (pd.errors.ParserError, pd.errors.EmptyDataError) as e:
            raise FormatError(f"invalid CSV ({str(e).strip()})", path) from None
        missing = {"session", "role", "motion"} - set(df.columns)
        if missing:
            raise FormatError(f"manifest CSV lacks columns {sorted(missing)}", path, "line 1")
        rows = [{**{k: v for k, v in r.items() if not (isinstance(v, float) and pd.isna(v))}, "_where": f"line {i + 2}"}
                for i, r in enumerate(df.to_dict("records"))]
    else:
        raise FormatError("manifest must be .yaml, .yml or .csv", path)
    by_session: dict[str, list[Participant]] = {}
    for r in rows:
        def resolve(key):
            v = r.get(key)
            if v is None or v == "":
                return None
            p = (base / str(v)).resolve()
            if not p.is_file():
                raise MissingFileError(f"{r['_where']}: {key} file not found (named by {path.name})", p)
            return p
        motion = resolve("motion")
        if motion is None:
            raise FormatError(f"{r['_where']}: no motion file", path, r["_where"])
        if r.get("role") in (None, ""):
            raise FormatError("no role", path, r["_where"])
        ch = r.get("audio_channel")
        if ch is not None:
            try:
                ch = int(ch)
            except (TypeError, ValueError):
                raise FormatError(f"audio_channel must be a whole number, got {ch!r}", path, r["_where"]) from None
        role = str(r["role"])
        part = Participant(role, characters.get(role, str(r.get("character", role))), motion, resolve("audio"),
                           resolve("transcript"), ch, str(r["session"]), listed_in=path)
        by_session.setdefault(str(r["session"]), []).append(part)
    sessions = []
    for name, parts in by_session.items():
        if len(parts) != 2:
            raise CorpusError(f"session {name!r} has {len(parts)} participants, expected 2", path)
        sessions.append(Session(name, tuple(parts)))
    corpus = Corpus(base, sessions, {"manifest": str(path)})
    if check:
        for s in sessions:
            for p in s.participants:
                check_durations(p, tolerance)
    return corpus


def load_corpus(path: str | Path, layout: str = "auto", fps: float = 30, tolerance: float = 1.0,
                check_durations: bool = True, characters: dict | None = None) -> Corpus:
    """Open a dyadic corpus: a GENEA-layout folder or a manifest file (``layout='auto'`` decides);
    ``characters`` (role -> character name) as in :func:`load_genea` and :func:`load_manifest`."""
    path = Path(path)
    if layout == "auto":
        layout = "genea" if path.is_dir() else "manifest"
    if layout == "genea":
        return load_genea(path, tolerance, check_durations, characters)
    if layout == "manifest":
        return load_manifest(path, tolerance, check_durations, characters)
    raise CorpusError(f"unknown corpus layout {layout!r} (expected auto, genea or manifest)", path)
