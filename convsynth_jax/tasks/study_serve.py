"""Task ``study_serve``: serve a built study folder to participants (uvicorn on ``task.host``:``task.port``).

``convsynth task=study_serve task.study=DIR [task.port=8000] [task.admin_token=...]``; answers go to
``task.db`` (default ``DIR/answers.sqlite``, SQLite in WAL mode). The admin export
(``/admin/export.csv``) needs ``Authorization: Bearer <token>`` with the token of ``task.admin_token``
or the environment variable ``CONVSYNTH_STUDY_ADMIN_TOKEN``; without one the export is disabled.
Behind a reverse proxy that serves the study under a path prefix, set ``task.root_path`` to it
(docs/study.md). Runs until stopped (Ctrl-C / SIGTERM).
"""
from __future__ import annotations

import logging
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

from ..errors import ConfigError

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class StudyServeSettings:
    """``conf/task/study_serve.yaml``."""

    name: str = "study_serve"
    study: Optional[str] = None                    # the folder task=study_build wrote
    db: Optional[str] = None                       # null: <study>/answers.sqlite
    host: str = "127.0.0.1"
    port: int = 8000
    admin_token: Optional[str] = None              # null: $CONVSYNTH_STUDY_ADMIN_TOKEN (unset: export disabled)
    trials_per_participant: Optional[int] = None   # null: the manifest's
    attention_per_participant: Optional[int] = None
    root_path: str = ""                            # path prefix under a reverse proxy, e.g. /study
    max_body_bytes: int = 2048
    title: str = "Motion study"


def make_app(s: StudyServeSettings):
    from ..study.server import create_app

    if not s.study:
        raise ConfigError("task=study_serve needs task.study=DIR (a task=study_build folder)", where="task.study")
    token = s.admin_token or os.environ.get("CONVSYNTH_STUDY_ADMIN_TOKEN") or None
    if token is not None and len(token) < 16:
        raise ConfigError("the admin token must have at least 16 characters", where="task.admin_token")
    db = Path(s.db) if s.db else Path(s.study) / "answers.sqlite"
    return create_app(s.study, db, admin_token=token, trials=s.trials_per_participant, attention=s.attention_per_participant,
                      max_body_bytes=s.max_body_bytes, title=s.title, root_path=s.root_path), db, token is not None


def run(cfg, out_dir: Path) -> dict:
    from ..config import task_settings

    s = task_settings(cfg)
    app, db, export = make_app(s)
    try:
        import uvicorn
    except ImportError as e:  # pragma: no cover - the optional extra
        raise ConfigError("task=study_serve needs the web extra: pip install 'convsynth_jax[study]'") from e
    log.info("serving %s on http://%s:%d%s (answers: %s; admin export %s)", s.study, s.host, s.port, s.root_path, db,
             "on" if export else "off: no admin token")
    uvicorn.run(app, host=s.host, port=int(s.port), root_path=s.root_path, proxy_headers=True, log_level="warning")
    counts = app.state.store.counts()
    return {"study": str(s.study), "db": str(db), **counts}
