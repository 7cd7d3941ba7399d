"""What the viewer shows, computed in Python: each character's joint positions per frame (forward
kinematics of its BVH, :func:`convsynth_jax.kinematics.forward_kinematics_np`), its bones, head and
hands, the audio files, the audio labels (PC, LR, HP) per character and the synthetic transitions.

``load_scene(path)`` reads a BVH file, a folder of BVH files, or an output folder of
``task=synthesize`` (its ``report.json``: each character's role, so ``<role>_input.wav`` is that
character's audio; the labels; the transitions) or ``task=converse`` (``A.bvh``, ``B.bvh``,
``conversation.wav``). The scene is a JSON-able dict (:func:`scene_script` makes the
``scene.js`` the page loads). Positions are integers in units of ``scale`` (a 4000th of the tallest
body's height), frame-major: ``positions[(f * J + j) * 3 + axis]``. Fingers (joints below a hand)
are dropped: the hand's sphere stands for them. Characters keep the places their BVH root gives
them (a synthesize or converse output seats both characters facing each other).
"""
from __future__ import annotations

import json
import logging
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import ConvSynthError, FormatError, MissingFileError

log = logging.getLogger(__name__)



def label_kinds() -> tuple:
    """The audio labels a timeline shows: every label of the registry but idle (``annotate/kinds.py``;
    a registered kind's label shows too), e.g. ("PC", "LR", "HP")."""
    from ..annotate.kinds import AUDIO_LABELS

    return tuple(k for k in AUDIO_LABELS if k != "idle")


COLORS = ("#345ca8", "#ba5434", "#3f8f4f", "#8a4fa0")     # character 0, 1, 2, 3
AUDIO_SUFFIXES = (".wav",)
MAX_FILES = 8


@dataclass(frozen=True)
class SceneFiles:
    """The files one scene reads: motion, audio (served to the page), the report (if any)."""

    bvh: tuple
    audio: tuple = ()
    report: Path | None = None
    extra_audio: tuple = field(default=())   # given by task.audio (outside the output folder allowed)


def _bvh_files(p: Path) -> list[Path]:
    """The BVH files of ``p`` (:func:`convsynth_jax.io.bvh.bvh_files`), at most ``MAX_FILES`` of a folder."""
    from ..io.bvh import bvh_files

    files = bvh_files(p)
    if len(files) > MAX_FILES:
        log.warning("%s holds %d BVH files; showing the first %d", p, len(files), MAX_FILES)
        files = files[:MAX_FILES]
    return files


def _read_report(path: Path) -> dict:
    try:
        rep = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise FormatError(f"not a JSON report ({e})", path) from None
    if not isinstance(rep, dict):
        raise FormatError("not a report (expected a JSON object)", path)
    return rep


def body(motion, name: str, color: str) -> dict:
    """One character: positions (frame-major, float64, not yet quantized), bones, head, hands."""
    from ..kinematics import forward_kinematics_np
    from ..rig import find_role

    sk = motion.skeleton
    pos = forward_kinematics_np(motion)
    if not np.all(np.isfinite(pos)):
        raise FormatError("forward kinematics gives non-finite joint positions", name)
    parents = [int(p) for p in sk.parents]
    hands = [j for j in (find_role(sk, "left_hand"), find_role(sk, "right_hand")) if j is not None]
    head = find_role(sk, "head")
    drop = sk.below(hands)               # joints below a hand
    keep = [j for j in range(len(parents)) if j not in drop]
    new = {j: k for k, j in enumerate(keep)}
    bones = [[new[parents[j]], new[j]] for j in keep if parents[j] >= 0 and parents[j] in new]
    return {"name": name, "color": color, "fps": float(motion.fps), "frames": int(motion.num_frames),
            "joints": len(keep), "joint_names": [sk.names[j] for j in keep], "bones": bones,
            "head": None if head is None or head not in new else new[head], "hands": [new[h] for h in hands if h in new],
            "_pos": pos[:, keep, :]}


def _labels_from_report(rep: dict, chars: list[str], fps: dict) -> dict:
    """character -> [{kind, start, end}] (seconds): the report's ``segments`` (per character), or a
    synthesize report's checker details (PC, LR of the character; PH: the partner's HP)."""
    from ..annotate.kinds import segment_kinds

    kinds = label_kinds()
    out = {c: [] for c in chars}
    segs = rep.get("segments")
    if isinstance(segs, dict):
        for c, rows in segs.items():
            if c in out and isinstance(rows, list):
                out[c] = [{"kind": str(r["kind"]), "start": float(r["start"]), "end": float(r["end"])}
                          for r in rows if isinstance(r, dict) and r.get("kind") in kinds]
        return out
    info = rep.get("characters") or {}
    for c in chars:
        det = ((info.get(c) or {}).get("checker") or {}).get("details") or []
        others = [o for o in chars if o != c]
        for d in det:
            if not isinstance(d, dict) or "start" not in d or "end" not in d:
                continue
            kind, who = d.get("kind"), c
            ck = next((k for k in segment_kinds() if k.name == kind), None)
            if ck is None:
                continue
            kind = ck.label
            if ck.channel == "partner":  # e.g. the partner's hesitation pause, as this character's search saw it
                if not others:
                    continue
                who = others[0]
            if kind not in kinds:
                continue
            row = {"kind": kind, "start": float(d["start"]) / fps[c], "end": float(d["end"]) / fps[c]}
            if row not in out[who]:
                out[who].append(row)
    for c in out:
        out[c].sort(key=lambda r: (kinds.index(r["kind"]), r["start"]))
    return out


def _transitions_from_report(rep: dict, chars: list[str], fps: dict) -> dict:
    out = {}
    info = rep.get("characters") or {}
    for c in chars:
        tr = (info.get(c) or {}).get("transitions") or []
        frames = [t.get("frame") if isinstance(t, dict) else t for t in tr]
        out[c] = [float(f) / fps[c] for f in frames if isinstance(f, (int, float))]
    return out


def find_files(path: str | Path, audio=None) -> SceneFiles:
    """The files of the scene at ``path`` (see the module's doc); ``audio``: WAV files given by the
    user (a path or a list), replacing the output folder's."""
    p = Path(path)
    files = _bvh_files(p)
    report = p / "report.json" if p.is_dir() and (p / "report.json").is_file() else None
    given = [audio] if isinstance(audio, (str, Path)) else list(audio or [])
    extra = []
    for a in given:
        a = Path(a)
        if not a.is_file():
            raise MissingFileError("audio file not found (task.audio)", a)
        if a.suffix.lower() not in AUDIO_SUFFIXES:
            raise FormatError("not a .wav file (task.audio)", a)
        extra.append(a)
    found = []
    if not extra and p.is_dir():
        found = sorted(q for q in p.iterdir() if q.suffix.lower() in AUDIO_SUFFIXES and q.is_file())
    return SceneFiles(tuple(files), tuple(found), report, tuple(extra))


def load_scene(path: str | Path, audio=None, title: str | None = None) -> dict:
    """The scene of ``path`` as a JSON-able dict (audio URLs are filled in by the caller: each
    ``audio`` entry has ``file``, the path on disk, and ``name``, a unique file name)."""
    from ..io import load_audio, load_bvh

    files = find_files(path, audio)
    rep = _read_report(files.report) if files.report else {}
    motions = [load_bvh(f) for f in files.bvh]
    chars = [f.stem for f in files.bvh]
    bodies = [body(m, c, COLORS[k % len(COLORS)]) for k, (m, c) in enumerate(zip(motions, chars))]
    fps = {b["name"]: b["fps"] for b in bodies}
    labels = _labels_from_report(rep, chars, fps) if rep else {c: [] for c in chars}
    trans = _transitions_from_report(rep, chars, fps) if rep else {c: [] for c in chars}
    info = rep.get("characters") or {}
    audio_files = list(files.extra_audio or files.audio)
    tracks = []
    used = set()
    for a in audio_files:
        snd = load_audio(a)                       # a clear error for an unreadable WAV
        owner = None
        for c in chars:                           # synthesize: <role>_input.wav belongs to the character of that role
            role = (info.get(c) or {}).get("role")
            if role and a.name == f"{role}_input.wav":
                owner = c
        name = a.name
        k = 1
        while name in used:
            name = f"{a.stem}_{k}{a.suffix}"
            k += 1
        used.add(name)
        tracks.append({"name": name, "file": str(a), "character": owner,
                       "duration": float(len(snd.samples)) / float(snd.sample_rate)})
    height = max(float(np.ptp(b["_pos"][..., 1])) for b in bodies) or 1.0
    scale = height / 4000.0
    for b in bodies:
        b["positions"] = np.rint(b.pop("_pos") / scale).astype(np.int64).ravel().tolist()
        b["labels"] = labels.get(b["name"], [])
        b["transitions"] = trans.get(b["name"], [])
    duration = max([b["frames"] / b["fps"] for b in bodies] + [t["duration"] for t in tracks])
    return {"title": title or Path(path).name, "source": str(path), "duration": duration, "scale": scale,
            "height": height, "characters": bodies, "audio": tracks, "kinds": list(label_kinds())}


def error_scene(e: BaseException, path) -> dict:
    return {"error": str(e), "source": str(path)}


def try_load_scene(path, audio=None, title=None) -> dict:
    """:func:`load_scene`, or an error scene naming the file and place (logged) for bad input."""
    try:
        return load_scene(path, audio, title)
    except (ConvSynthError, OSError) as e:
        log.error("viewer: %s", e)
        return error_scene(e, path)


def public(scene: dict, url_of) -> dict:
    """The scene as the page gets it: audio entries carry ``url`` (``url_of(name)``), not paths on disk."""
    out = dict(scene)
    if "audio" in scene:
        out["audio"] = [{k: v for k, v in t.items() if k != "file"} | {"url": url_of(t["name"])} for t in scene["audio"]]
        out.pop("source", None)
    return out


def scene_script(scene: dict) -> str:
    """``scene.js``: a classic script that sets ``window.CONVSYNTH_SCENE`` (works from file://)."""
    text = json.dumps(scene, separators=(",", ":"), allow_nan=False)
    text = text.replace("</", "<\\/")             # never closes a script element
    return f"window.CONVSYNTH_SCENE = {text};\n"
