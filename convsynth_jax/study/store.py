"""SQLite store of a study: participants with their assigned trials, and one row per answer.

WAL journal mode and ``synchronous=FULL``: an answer acknowledged to the browser was committed to
the write-ahead log and fsynced, so a server killed at any moment (SIGKILL) loses no acknowledged
answer (``tests/test_study_server.py``). Every write is one ``BEGIN IMMEDIATE`` transaction.

Idempotency: ``answers`` has a primary key (participant, trial). A re-sent answer with the same
choice returns the stored row; a different choice for an answered trial is refused (the first
answer stands).
"""
from __future__ import annotations

import json
import secrets
import sqlite3
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from ..errors import ConvSynthError

SCHEMA = """
CREATE TABLE IF NOT EXISTS participants (
    token TEXT PRIMARY KEY,
    created REAL NOT NULL,
    trials TEXT NOT NULL,            -- JSON list of stimulus ids, in presentation order
    completed REAL,
    completion_code TEXT
);
CREATE TABLE IF NOT EXISTS answers (
    participant TEXT NOT NULL REFERENCES participants(token),
    trial INTEGER NOT NULL,          -- index into the participant's trials
    stimulus TEXT NOT NULL,
    chosen_side TEXT NOT NULL CHECK (chosen_side IN ('left', 'right')),
    chosen_condition TEXT NOT NULL,
    response_ms INTEGER NOT NULL,
    created REAL NOT NULL,
    PRIMARY KEY (participant, trial)
);
CREATE TABLE IF NOT EXISTS assignments (
    stimulus TEXT PRIMARY KEY,
    count INTEGER NOT NULL
);
"""

ANSWER_COLUMNS = ("participant", "trial", "stimulus", "chosen_side", "chosen_condition", "response_ms", "created")


class StudyStoreError(ConvSynthError):
    """The study database cannot be opened or is inconsistent."""


class AnswerConflict(ConvSynthError):
    """A trial already answered with a different choice (the first answer stands)."""


@dataclass(frozen=True)
class StudyParticipant:
    token: str
    trials: tuple[str, ...]
    completed: bool
    completion_code: str | None


class Store:
    """One SQLite file; a connection per thread (the web server's worker threads)."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self._local = threading.local()
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            con = self._con()
            mode = con.execute("PRAGMA journal_mode=WAL").fetchone()[0]
            if mode.lower() != "wal":
                raise StudyStoreError(f"journal mode is {mode!r}, WAL needed", self.path)
            con.executescript(SCHEMA)
        except sqlite3.DatabaseError as e:
            raise StudyStoreError(f"not a usable study database ({e})", self.path) from None

    def _con(self) -> sqlite3.Connection:
        con = getattr(self._local, "con", None)
        if con is None:
            con = sqlite3.connect(self.path, timeout=30.0, isolation_level=None, check_same_thread=True)
            con.execute("PRAGMA synchronous=FULL")
            con.execute("PRAGMA foreign_keys=ON")
            con.execute("PRAGMA busy_timeout=30000")
            self._local.con = con
        return con

    def _write(self, fn):
        """Run ``fn(con)`` in one BEGIN IMMEDIATE transaction (committed, or rolled back on error)."""
        con = self._con()
        con.execute("BEGIN IMMEDIATE")
        try:
            out = fn(con)
        except BaseException:
            con.execute("ROLLBACK")
            raise
        con.execute("COMMIT")
        return out

    # ----------------------------------------------------------------------------- participants
    def create_participant(self, choose_trials) -> StudyParticipant:
        """A new participant whose trials are ``choose_trials(counts, index)`` (counts: stimulus ->
        participants assigned so far; index: participants before this one), chosen and recorded in
        the same transaction, so concurrent sign-ups see each other's assignments."""
        token = secrets.token_urlsafe(18)

        def tx(con):
            counts = dict(con.execute("SELECT stimulus, count FROM assignments").fetchall())
            index = con.execute("SELECT COUNT(*) FROM participants").fetchone()[0]
            trials = list(choose_trials(counts, index))
            con.execute("INSERT INTO participants (token, created, trials) VALUES (?, ?, ?)",
                        (token, time.time(), json.dumps(trials)))
            con.executemany("INSERT INTO assignments (stimulus, count) VALUES (?, 1) "
                            "ON CONFLICT(stimulus) DO UPDATE SET count = count + 1", [(s,) for s in set(trials)])
            return trials

        trials = self._write(tx)
        return StudyParticipant(token, tuple(trials), False, None)

    def participant(self, token: str) -> StudyParticipant | None:
        if not isinstance(token, str) or not token:
            return None
        row = self._con().execute("SELECT trials, completed, completion_code FROM participants WHERE token = ?",
                                  (token,)).fetchone()
        if row is None:
            return None
        return StudyParticipant(token, tuple(json.loads(row[0])), row[1] is not None, row[2])

    def answered(self, token: str) -> dict[int, dict]:
        """trial index -> answer row of one participant."""
        rows = self._con().execute(f"SELECT {', '.join(ANSWER_COLUMNS)} FROM answers WHERE participant = ? ORDER BY trial",
                                   (token,)).fetchall()
        return {r[1]: dict(zip(ANSWER_COLUMNS, r)) for r in rows}

    def record_answer(self, token: str, trial: int, stimulus: str, side: str, condition: str, response_ms: int) -> tuple[dict, bool]:
        """(the stored row, whether this call inserted it). Raises AnswerConflict when the trial
        was already answered with another side."""
        def tx(con):
            cur = con.execute("INSERT INTO answers (participant, trial, stimulus, chosen_side, chosen_condition, response_ms, created) "
                              "VALUES (?, ?, ?, ?, ?, ?, ?) ON CONFLICT(participant, trial) DO NOTHING",
                              (token, trial, stimulus, side, condition, int(response_ms), time.time()))
            row = con.execute(f"SELECT {', '.join(ANSWER_COLUMNS)} FROM answers WHERE participant = ? AND trial = ?",
                              (token, trial)).fetchone()
            return dict(zip(ANSWER_COLUMNS, row)), cur.rowcount == 1

        row, inserted = self._write(tx)
        if not inserted and row["chosen_side"] != side:
            raise AnswerConflict(f"trial {trial} was already answered ({row['chosen_side']})")
        return row, inserted

    def complete(self, token: str) -> str:
        """The participant's completion code (made once, on the first call after the last answer)."""
        code = secrets.token_hex(4).upper()

        def tx(con):
            con.execute("UPDATE participants SET completed = ?, completion_code = ? WHERE token = ? AND completed IS NULL",
                        (time.time(), code, token))
            return con.execute("SELECT completion_code FROM participants WHERE token = ?", (token,)).fetchone()[0]

        return self._write(tx)

    # ----------------------------------------------------------------------------- export
    def answers(self) -> list[dict]:
        rows = self._con().execute(f"SELECT {', '.join(ANSWER_COLUMNS)} FROM answers ORDER BY participant, trial").fetchall()
        return [dict(zip(ANSWER_COLUMNS, r)) for r in rows]

    def counts(self) -> dict:
        con = self._con()
        return {"participants": con.execute("SELECT COUNT(*) FROM participants").fetchone()[0],
                "completed": con.execute("SELECT COUNT(*) FROM participants WHERE completed IS NOT NULL").fetchone()[0],
                "answers": con.execute("SELECT COUNT(*) FROM answers").fetchone()[0]}

    def close(self) -> None:
        con = getattr(self._local, "con", None)
        if con is not None:
            con.close()
            self._local.con = None
