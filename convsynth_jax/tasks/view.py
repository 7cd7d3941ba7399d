"""Task ``view``: ``convsynth task=view path=FILE.bvh|DIR|OUTPUT_DIR`` plays the motion in 3D in the
browser with its audio (:mod:`convsynth_jax.viewer`, docs/viewer.md).

Served by uvicorn on ``task.host``:``task.port`` (loopback by default) until stopped (Ctrl-C /
SIGTERM); ``task.export=DIR`` instead writes the page as one folder that opens from the file system
(nothing is served). ``task.audio`` (a WAV or a list of WAVs) replaces the output folder's audio. A
missing or malformed input is reported in the page and the log while serving, and fails the export.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Optional

from ..errors import ConfigError

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ViewSettings:
    """``conf/task/view.yaml`` (the file or folder: top-level ``path``)."""

    name: str = "view"
    host: str = "127.0.0.1"
    port: int = 8010
    audio: Any = None                   # null: the output folder's WAVs; a WAV or a list of WAVs
    export: Optional[str] = None        # a folder: write the static viewer there instead of serving
    title: Optional[str] = None         # null: the input's name


def _audio(a):
    if a is None:
        return None
    if isinstance(a, str):
        return [a]
    if isinstance(a, (list, tuple)) and all(isinstance(x, str) for x in a):
        return list(a)
    raise ConfigError(f"task.audio must be a WAV file or a list of them, got {a!r}", where="task.audio")


def run(cfg, out_dir: Path) -> dict:
    from ..config import task_settings

    s = task_settings(cfg)
    if not cfg.get("path"):
        raise ConfigError("task=view needs path=FILE.bvh, path=DIR or path=OUTPUT_DIR", where="path")
    path = Path(str(cfg.path))
    audio = _audio(s.audio)
    if s.export:
        from ..viewer.server import export

        return export(path, Path(s.export), audio=audio, title=s.title)
    from ..viewer.server import create_viewer_app

    app = create_viewer_app(path, audio=audio, title=s.title)
    scene = app.state.source.get()
    try:
        import uvicorn
    except ImportError as e:  # pragma: no cover - the optional extra
        raise ConfigError("task=view needs the web extra: pip install 'convsynth_jax[study]'") from e
    if "error" not in scene:
        log.info("viewing %s (%d characters, %d audio files, %.2f s)", path, len(scene["characters"]), len(scene["audio"]),
                 scene["duration"])
    log.info("open http://%s:%d/ (add ?t=SECONDS to open at a time); Ctrl-C stops", s.host, int(s.port))
    uvicorn.run(app, host=s.host, port=int(s.port), log_level="warning")
    return {"path": str(path), "host": s.host, "port": int(s.port), "error": scene.get("error")}
