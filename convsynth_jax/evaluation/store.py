"""A results store that makes sweeps resumable: each job's table kept under the hash of its configuration.

A leave-one-out job (``task=loo``) is identified by its resolved configuration (which includes the
system, the fold and the condition), the content of its corpus
(:func:`convsynth_jax.io.corpus.corpus_fingerprint`) and the package's code: :func:`job_key` hashes them. Its result
goes to ``<store>/<key>/`` (``cases.csv`` and ``record.json``: key, system, fold, condition, the
configuration, when it was written). An entry is written into a temporary folder and renamed into
place when complete (``record.json`` last), so an entry is either complete or absent: a job killed
while it writes leaves only a hidden ``.<key>.*`` folder, which readers ignore and the next writer of
that key removes. A re-run of the same sweep finds the completed jobs' entries and skips them
(``task.resume``), redoing only the missing ones; while a job computes it holds its key's lock, so two
processes running the same job at once compute it once.

The key includes a hash of the package's source files
(:func:`convsynth_jax.fingerprint.code_fingerprint`), so an edited library never reuses results of
the old code, and a hash of the corpus's files, so a corpus edited in place (a BVH fixed, names
unchanged) is computed again (the old entries stay until the store is deleted).
``task=collect task.store=DIR`` reads every complete entry (:func:`collect_store`).
"""
from __future__ import annotations

import datetime
import hashlib
import json
import logging
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from ..errors import FormatError, MissingFileError
from ..fingerprint import code_fingerprint  # noqa: F401  (the one home; re-exported)
from ..utils import _umask, file_lock, replace_dir, write_error, write_json_atomic

log = logging.getLogger(__name__)

RECORD = "record.json"
CASES = "cases.csv"


def job_key(config: dict, code: str) -> str:
    """The store key of a job: a SHA-256 (first 24 hex digits) of its resolved configuration (a plain,
    JSON-serializable dict; keys in any order) and ``code`` (:func:`code_fingerprint`)."""
    text = json.dumps({"config": config, "code": code}, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:24]


@dataclass(frozen=True)
class StoredJob:
    """A complete entry: its table and its record."""

    key: str
    cases: pd.DataFrame
    record: dict


class ResultStore:
    """The folder ``root`` holding one complete entry per finished job (module docstring)."""

    def __init__(self, root: str | Path):
        self.root = Path(root)

    def entry(self, key: str) -> Path:
        return self.root / key

    def read(self, key: str) -> StoredJob | None:
        """The complete entry of ``key``, or None when there is none. An entry whose files cannot be read
        is reported and treated as missing (recomputed)."""
        d = self.entry(key)
        if not (d / RECORD).is_file():
            return None
        try:
            record = json.loads((d / RECORD).read_text())
            cases = pd.read_csv(d / CASES)
        except (OSError, ValueError) as e:
            log.warning("%s: unreadable stored result (%s); computing it again", d, e)
            return None
        return StoredJob(key, cases, record)

    def claim(self, key: str):
        """The key's inter-process lock (hold it while computing the job)."""
        return file_lock(self.entry(key))

    def write(self, key: str, cases: pd.DataFrame, record: dict) -> Path:
        """Store a finished job's table and record as the complete entry of ``key`` (atomically)."""
        try:
            self.root.mkdir(parents=True, exist_ok=True)
            self._remove_partial(key)
            tmp = Path(tempfile.mkdtemp(prefix=f".{key}.", dir=self.root))
        except OSError as e:
            raise write_error(e, self.entry(key)) from None
        try:
            cases.to_csv(tmp / CASES, index=False)
            written = datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")
            write_json_atomic(tmp / RECORD, {**record, "key": key, "written": written})
            os.chmod(tmp, 0o777 & ~_umask())  # mkdtemp makes it private
            return replace_dir(tmp, self.entry(key))
        except BaseException as e:
            shutil.rmtree(tmp, ignore_errors=True)  # a partial entry is never left visible
            if isinstance(e, OSError) and write_error(e, self.entry(key)) is not e:
                raise write_error(e, self.entry(key)) from None
            raise

    def _remove_partial(self, key: str) -> None:
        """Folders left by a writer of ``key`` that was killed (the caller holds the key's lock)."""
        for p in self.root.glob(f".{key}.*"):
            if p.is_dir():
                log.info("removing a partial stored result %s", p)
                shutil.rmtree(p, ignore_errors=True)

    def keys(self) -> list[str]:
        """Keys of the complete entries (sorted)."""
        if not self.root.is_dir():
            return []
        return sorted(p.name for p in self.root.iterdir() if not p.name.startswith(".") and (p / RECORD).is_file())


def collect_store(root: str | Path) -> pd.DataFrame:
    """Every complete entry's cases in one table (rows in key order; ``job_key`` names the entry).
    Partial entries (hidden folders) are skipped."""
    store = ResultStore(root)
    if not store.root.is_dir():
        raise MissingFileError("results store not found", store.root)
    frames = []
    for key in store.keys():
        job = store.read(key)
        if job is None:
            raise FormatError("stored result cannot be read", store.entry(key))
        frames.append(job.cases.assign(job_key=key))
    if not frames:
        return pd.DataFrame(columns=["fold", "condition", "status", "success", "job_key"])
    return pd.concat(frames, ignore_index=True)
