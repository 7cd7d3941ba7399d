"""Folders of NumPy arrays with a checksummed manifest: the on-disk form of large motion databases and
motion graphs (memory-mappable ``.npy`` files, one per array), and the shards of a sharded build.

A folder holds ``<name>.npy`` per array and ``manifest.json`` ({"arrays": {name: {file, sha256,
shape, dtype}}, "meta": {...}}). It is written into a temporary sibling folder and renamed into place,
so a reader never sees a half-written folder; :func:`read_array_folder` checks the checksums
(``verify``) and names the file that does not match.
"""
from __future__ import annotations

import hashlib
import json
import shutil
import tempfile
from pathlib import Path

import numpy as np

from ..annotate.types import FrameAudio
from ..errors import GraphError, MissingFileError
from ..utils import atomic_path, replace_dir
from .database import MotionDatabase
from .types import MotionGraph

MANIFEST = "manifest.json"


def file_sha256(path: str | Path, chunk: int = 1 << 22) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while True:
            b = fh.read(chunk)
            if not b:
                break
            h.update(b)
    return h.hexdigest()


def save_npz_atomic(path: str | Path, **arrays) -> str:
    """Write an uncompressed .npz atomically; returns its sha256."""
    with atomic_path(path, suffix=".npz") as tmp:
        with open(tmp, "wb") as fh:
            np.savez(fh, **arrays)
    return file_sha256(path)


def write_array_folder(folder: str | Path, arrays: dict, meta: dict) -> Path:
    """Write ``arrays`` (name -> ndarray) and ``meta`` (JSON-ready) as a folder, atomically replacing
    any folder of that name."""
    folder = Path(folder)
    folder.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{folder.name}.", dir=folder.parent))
    try:
        entries = {}
        for name, arr in arrays.items():
            arr = np.ascontiguousarray(arr)
            f = tmp / f"{name}.npy"
            np.save(f, arr, allow_pickle=False)
            entries[name] = {"file": f.name, "sha256": file_sha256(f), "shape": list(arr.shape), "dtype": str(arr.dtype)}
        (tmp / MANIFEST).write_text(json.dumps({"arrays": entries, "meta": meta}, indent=1, default=float) + "\n")
        replace_dir(tmp, folder)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return folder


def read_array_folder(folder: str | Path, mmap: bool = True, verify: bool = True) -> tuple[dict, dict]:
    """(arrays, meta) of a folder written by :func:`write_array_folder`; arrays memory-mapped
    (read-only) with ``mmap``. ``verify`` checks every file's sha256 first."""
    folder = Path(folder)
    man = folder / MANIFEST
    if not man.is_file():
        raise MissingFileError("array folder has no manifest.json", folder)
    try:
        info = json.loads(man.read_text())
        entries = info["arrays"]
    except (ValueError, KeyError) as e:
        raise GraphError(f"unreadable manifest ({e})", man) from None
    arrays = {}
    for name, e in entries.items():
        f = folder / e["file"]
        if not f.is_file():
            raise MissingFileError(f"array {name!r} listed in the manifest is missing", f)
        if verify and file_sha256(f) != e["sha256"]:
            raise GraphError(f"checksum mismatch for array {name!r} (file changed or truncated)", f)
        arrays[name] = np.load(f, mmap_mode="r" if mmap else None, allow_pickle=False)
        if list(arrays[name].shape) != list(e["shape"]):
            raise GraphError(f"array {name!r} has shape {arrays[name].shape}, manifest says {e['shape']}", f)
    return arrays, info.get("meta", {})


_AUDIO = ("label", "seg_start", "seg_end", "seg_peak")


def save_database(db: MotionDatabase, folder: str | Path, meta: dict | None = None) -> Path:
    """A motion database as an array folder (positions, velocities, ..., own_*/partner_* audio)."""
    arrays = {"positions": db.positions, "velocities": db.velocities, "weights": db.weights, "clip": db.clip,
              "frame": db.frame, "offsets": db.offsets}
    for side, fa in (("own", db.own), ("partner", db.partner)):
        arrays.update({f"{side}_{k}": getattr(fa, k) for k in _AUDIO})
    if db.joint_turn is not None:
        arrays["joint_turn"] = db.joint_turn
    m = {"clip_names": list(db.clip_names), "fps": float(db.fps), "joint_names": list(db.joint_names),
         "db_meta": db.meta, **(meta or {})}
    return write_array_folder(folder, arrays, m)


def load_database(folder: str | Path, mmap: bool = True, verify: bool = True) -> MotionDatabase:
    """The database saved by :func:`save_database` (arrays memory-mapped with ``mmap``)."""
    a, m = read_array_folder(folder, mmap=mmap, verify=verify)
    try:
        audio = [FrameAudio(*(a[f"{side}_{k}"] for k in _AUDIO)) for side in ("own", "partner")]
        return MotionDatabase(tuple(m["clip_names"]), float(m["fps"]), a["positions"], a["velocities"], a["weights"],
                              a["clip"], a["frame"], a["offsets"], audio[0], audio[1], tuple(m["joint_names"]),
                              dict(m.get("db_meta", {})), joint_turn=a.get("joint_turn"))
    except KeyError as e:
        raise GraphError(f"not a motion database folder (missing {e})", folder) from None


def save_graph_folder(graph: MotionGraph, folder: str | Path) -> Path:
    """A motion graph as an array folder (memory-mappable; :func:`load_graph_folder`)."""
    arrays = {k: np.asarray(getattr(graph, k)) for k in MotionGraph._ARRAYS}
    return write_array_folder(folder, arrays, {"clip_names": list(graph.clip_names), "fps": float(graph.fps),
                                               "graph_meta": graph.meta})


def load_graph_folder(folder: str | Path, mmap: bool = True, verify: bool = True) -> MotionGraph:
    a, m = read_array_folder(folder, mmap=mmap, verify=verify)
    try:
        return MotionGraph(tuple(m["clip_names"]), float(m["fps"]), meta=dict(m["graph_meta"]),
                           **{k: a[k] for k in MotionGraph._ARRAYS})
    except KeyError as e:
        raise GraphError(f"not a motion graph folder (missing {e})", folder) from None
