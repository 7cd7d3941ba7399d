"""The viewer's web application (Starlette; served by uvicorn in ``task=view``) and its static export.

Routes: ``/`` the page, ``/scene.js`` the scene (``window.CONVSYNTH_SCENE``; an error scene naming
the file and place when the input is missing or malformed, so the page shows the error), ``/static/<name>``
the page's scripts (a fixed list, from the package), ``/files/<name>`` the scene's audio files (only
the names the scene lists; nothing else of the disk, whatever the path). The scene is read again when
one of its files changes (a re-run of the task that wrote it shows after a reload).

:func:`export` writes the same page as one folder that opens from ``file://`` (the scene as a
script, the audio beside it, relative URLs only).
"""
from __future__ import annotations

import html
import logging
import shutil
import tempfile
from pathlib import Path

from ..errors import ConfigError, ConvSynthError, WriteError
from ..utils import replace_dir
from .scene import find_files, public, scene_script, try_load_scene

log = logging.getLogger(__name__)

STATIC = Path(__file__).resolve().parent / "static"
STATIC_FILES = {"viewer.js": STATIC / "viewer.js", "viewer.css": STATIC / "viewer.css",
                "three.bundle.min.js": STATIC / "vendor" / "three.bundle.min.js",
                "three.LICENSE": STATIC / "vendor" / "three.LICENSE"}
MEDIA_TYPES = {".js": "text/javascript", ".css": "text/css", ".wav": "audio/wav", ".LICENSE": "text/plain"}
SECURITY_HEADERS = {
    "X-Content-Type-Options": "nosniff",
    "Referrer-Policy": "no-referrer",
    "X-Frame-Options": "DENY",
    "Content-Security-Policy": "default-src 'self'; script-src 'self'; style-src 'self'; media-src 'self'; "
                               "img-src 'self' data:; connect-src 'self'",
    "Cache-Control": "no-store",
}


def page(title: str, prefix: str = "") -> str:
    """index.html: the same page for the server (``prefix`` '') and the export (relative URLs)."""
    t = html.escape(title)
    return (f"<!doctype html><html lang=en><head><meta charset=utf-8><title>{t}</title>"
            "<meta name=viewport content='width=device-width, initial-scale=1'><link rel=icon href='data:,'>"
            f"<link rel=stylesheet href='{prefix}viewer.css'></head><body>"
            f"<header><h1 id=title>{t}</h1><span id=status>loading…</span></header>"
            "<div id=error role=alert hidden></div>"
            "<main><div id=stage></div>"
            "<div id=controls><button id=play type=button>Play</button>"
            "<input id=scrub type=range min=0 max=1 step=0.001 value=0 aria-label='time'>"
            "<span id=clock>0.00 / 0.00 s</span>"
            "<label>speed <select id=speed><option>0.25</option><option>0.5</option><option selected>1</option>"
            "<option>1.5</option><option>2</option></select></label>"
            "<button id=reset-camera type=button>Reset view</button></div>"
            "<canvas id=timeline height=10></canvas><div id=legend></div><div id=audio></div></main>"
            f"<script src='{prefix}three.bundle.min.js'></script><script src='{prefix}scene.js'></script>"
            f"<script src='{prefix}viewer.js'></script></body></html>")


class SceneSource:
    """The scene of a path, read again when one of its files changes (or while it is an error)."""

    def __init__(self, path, audio=None, title=None):
        self.path, self.audio, self.title = path, audio, title
        self._key, self._scene = None, None

    def _signature(self):
        try:
            f = find_files(self.path, self.audio)
            files = [*f.bvh, *f.audio, *f.extra_audio, *([f.report] if f.report else [])]
            return tuple((str(p), p.stat().st_mtime_ns, p.stat().st_size) for p in files)
        except (ConvSynthError, OSError):
            return None

    def get(self) -> dict:
        key = self._signature()
        if key is None or key != self._key or self._scene is None or "error" in self._scene:
            self._scene = try_load_scene(self.path, self.audio, self.title)
            self._key = key
        return self._scene

    def audio_files(self) -> dict:
        """name -> path of every audio file the scene lists (the only files /files/ serves)."""
        return {t["name"]: Path(t["file"]) for t in self.get().get("audio", [])}


def create_viewer_app(path, audio=None, title: str | None = None):
    """The ASGI application showing ``path`` (a BVH file, a folder of them, a synthesize or
    converse output); ``audio``: WAV files replacing the folder's."""
    try:
        from starlette.applications import Starlette
        from starlette.middleware import Middleware
        from starlette.middleware.base import BaseHTTPMiddleware
        from starlette.responses import FileResponse, HTMLResponse, PlainTextResponse, Response
        from starlette.routing import Route
    except ImportError as e:  # pragma: no cover - the optional extra
        raise ConfigError("task=view needs the web extra: pip install 'convsynth_jax[study]'") from e

    source = SceneSource(path, audio, title)
    title = title or Path(path).name or str(path)

    async def headers(request, call_next):
        resp = await call_next(request)
        for k, v in SECURITY_HEADERS.items():
            resp.headers.setdefault(k, v)
        return resp

    def not_found():
        return PlainTextResponse("not found", status_code=404)

    async def index(request):
        return HTMLResponse(page(title))

    async def scene_js(request):
        return Response(scene_script(public(source.get(), lambda n: f"files/{n}")), media_type="text/javascript")

    async def static(request):
        f = STATIC_FILES.get(request.path_params["name"])
        if f is None or not f.is_file():
            return not_found()
        return FileResponse(f, media_type=MEDIA_TYPES.get(f.suffix, "text/plain"))

    async def files(request):
        name = request.path_params["name"]
        f = source.audio_files().get(name)
        if f is None or "/" in name or "\\" in name or not f.is_file():
            log.warning("viewer: refused /files/%s (not a file of the scene)", name)
            return not_found()
        return FileResponse(f, media_type="audio/wav")

    async def health(request):
        s = source.get()
        return Response('{"ok": %s}' % ("false" if "error" in s else "true"), media_type="application/json")

    routes = [Route("/", index), Route("/index.html", index), Route("/scene.js", scene_js), Route("/healthz", health),
              Route("/files/{name:str}", files), Route("/{name:str}", static)]
    app = Starlette(routes=routes, middleware=[Middleware(BaseHTTPMiddleware, dispatch=headers)])
    app.state.source = source
    return app


def export(path, target, audio=None, title: str | None = None) -> dict:
    """Write the viewer of ``path`` as one folder ``target`` (index.html, the scripts, scene.js, the
    audio under audio/) that opens from the file system. Written beside ``target`` and renamed into
    place: ``target`` is never half-written. A missing or malformed input raises (nothing written)."""
    from .scene import load_scene

    scene = load_scene(path, audio, title)
    target = Path(target)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.", dir=target.parent))
    except OSError as e:
        raise WriteError(f"cannot create the export folder ({e.strerror or e})", target) from None
    try:
        (tmp / "audio").mkdir()
        for t in scene["audio"]:
            shutil.copyfile(t["file"], tmp / "audio" / t["name"])
        for name, f in STATIC_FILES.items():
            shutil.copyfile(f, tmp / name)
        (tmp / "scene.js").write_text(scene_script(public(scene, lambda n: f"audio/{n}")))
        (tmp / "index.html").write_text(page(title or scene["title"], ""))
        tmp.chmod(0o755)
        replace_dir(tmp, target)
    except OSError as e:
        shutil.rmtree(tmp, ignore_errors=True)
        raise WriteError(f"cannot write the export ({e.strerror or e})", target) from None
    size = sum(p.stat().st_size for p in target.rglob("*") if p.is_file())
    log.info("exported the viewer of %s to %s (%d characters, %d audio files, %.1f MB): open %s", path, target,
             len(scene["characters"]), len(scene["audio"]), size / 1e6, target / "index.html")
    return {"export": str(target), "characters": [c["name"] for c in scene["characters"]],
            "audio": [t["name"] for t in scene["audio"]], "duration_s": scene["duration"], "bytes": size}
