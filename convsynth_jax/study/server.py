"""The study's web application (FastAPI on Starlette; served by uvicorn in ``task=study_serve``).

Pages: ``/`` consent (and resumption by token), ``/p/<token>/instructions``, ``/p/<token>/trial``
(the participant's next unanswered trial: the side-by-side video, a Play button, the two choice
buttons enabled only once the video has played to its end, a progress bar), ``/p/<token>/done``
(the completion code). API: ``POST /api/answer`` (JSON ``{trial, side, response_ms}``, the
participant's token in the ``X-Participant-Token`` header), ``GET /api/me`` (one's own progress),
``GET /admin/export.csv`` (every answer; ``Authorization: Bearer <admin token>``), ``GET /media/<id>.mp4``
(only files the manifest lists, from the study folder's ``media/``; range requests as Starlette's
FileResponse serves them).

Refusals: a missing token 401, an unknown token 403 (also a wrong admin token; no admin token
configured: export disabled, 403); a body over ``max_body_bytes`` 413; malformed JSON 400; a
well-formed answer with wrong fields 422; a trial outside the participant's list 404; a different
choice for an answered trial 409 (the first stands); an identical re-sent answer 200 and stored
once. No refusal writes to the store.
"""

import csv
import hmac
import html
import io
import json
import logging
import re
from pathlib import Path

from ..errors import ConfigError
from . import design
from .build import load_study_manifest
from .store import AnswerConflict, Store

log = logging.getLogger(__name__)

MEDIA_NAME = re.compile(r"^s\d{3,6}\.mp4$")
EXPORT_COLUMNS = ("participant", "trial", "stimulus", "kind", "pair", "condition_a", "condition_b", "left", "right",
                  "chosen_side", "chosen_condition", "expected", "response_ms", "created")
SECURITY_HEADERS = {
    "X-Content-Type-Options": "nosniff",
    "Referrer-Policy": "no-referrer",
    "X-Frame-Options": "DENY",
    "Content-Security-Policy": "default-src 'self'; script-src 'self'; style-src 'self' 'unsafe-inline'; media-src 'self'",
    "Cache-Control": "no-store",
}

CSS = """
body { font-family: system-ui, sans-serif; max-width: 960px; margin: 2em auto; padding: 0 1em; color: #222; }
.progress { background: #ddd; height: 10px; border-radius: 5px; margin: 0.5em 0 1em; }
.progress > div { background: #3a6fb0; height: 10px; border-radius: 5px; }
video { width: 100%; max-height: 62vh; background: #000; }
.choices { display: flex; justify-content: space-between; margin-top: 1em; }
.choices button, .play { font-size: 1.2em; padding: 0.6em 2em; }
button:disabled { opacity: 0.4; }
"""

TRIAL_JS = """
(function () {
  var d = document.body.dataset, v = document.getElementById('stimulus'), play = document.getElementById('play');
  var buttons = document.querySelectorAll('.choices button'), enabledAt = null, sent = false;
  play.addEventListener('click', function () { play.disabled = true; v.play(); });
  v.addEventListener('ended', function () {
    enabledAt = performance.now();
    buttons.forEach(function (b) { b.disabled = false; });
    document.getElementById('status').textContent = 'Which motion looked more natural?';
  });
  buttons.forEach(function (b) {
    b.addEventListener('click', function () {
      if (sent || enabledAt === null) { return; }
      sent = true;
      buttons.forEach(function (x) { x.disabled = true; });
      var body = JSON.stringify({trial: parseInt(d.trial, 10), side: b.dataset.side,
                                 response_ms: Math.round(performance.now() - enabledAt)});
      var send = function (tries) {
        fetch(d.root + '/api/answer', {method: 'POST', headers: {'Content-Type': 'application/json', 'X-Participant-Token': d.token},
                              body: body}).then(function (r) {
          if (r.ok || r.status === 409) { window.location.assign(d.root + '/p/' + d.token + '/trial'); }
          else { throw new Error('HTTP ' + r.status); }
        }).catch(function () {
          if (tries > 0) { setTimeout(function () { send(tries - 1); }, 1000); }
          else { document.getElementById('status').textContent = 'Could not save your answer; please reload the page.'; }
        });
      };
      send(5);
    });
  });
})();
"""


def _page(title: str, body: str, data: dict | None = None) -> str:
    attrs = "".join(f' data-{k}="{html.escape(str(v), quote=True)}"' for k, v in (data or {}).items())
    return (f"<!doctype html><html lang=en><head><meta charset=utf-8><title>{html.escape(title)}</title>"
            f"<meta name=viewport content='width=device-width, initial-scale=1'><style>{CSS}</style></head>"
            f"<body{attrs}>{body}</body></html>")


def create_app(study_dir: str | Path, db_path: str | Path, *, admin_token: str | None = None, trials: int | None = None,
               attention: int | None = None, seed: int | None = None, max_body_bytes: int = 2048, title: str = "Motion study",
               consent_text: str | None = None, root_path: str = ""):
    """The ASGI application of a built study folder. ``trials`` regular and ``attention``
    attention-check trials per participant (default: the manifest's ``trials_per_participant`` and
    ``attention_per_participant``); ``admin_token``: guards the export (None: export disabled);
    ``root_path``: the prefix a reverse proxy serves the study under (links carry it; the proxy
    strips it before forwarding)."""
    try:
        from fastapi import FastAPI, Request
        from fastapi.concurrency import run_in_threadpool
        from fastapi.responses import FileResponse, HTMLResponse, JSONResponse, PlainTextResponse, RedirectResponse, Response
    except ImportError as e:  # pragma: no cover - the optional extra
        raise ConfigError("task=study_serve needs the web extra: pip install 'convsynth_jax[study]'") from e

    R = html.escape(root_path.rstrip("/"), quote=True)
    study_dir = Path(study_dir).resolve()
    manifest = load_study_manifest(study_dir)
    info = manifest["study"]
    stimuli = {s["id"]: s for s in manifest["stimuli"]}
    media = {Path(s["file"]).name: study_dir / s["file"] for s in manifest["stimuli"]}
    n_trials = int(trials if trials is not None else info.get("trials_per_participant", 20))
    n_attention = int(attention if attention is not None else info.get("attention_per_participant", 0))
    seed = int(info.get("seed", 0) if seed is None else seed)
    n_trials = min(n_trials, sum(s["kind"] == "pair" for s in stimuli.values()))
    store = Store(db_path)
    stimulus_list = list(stimuli.values())

    app = FastAPI(title=title, docs_url=None, redoc_url=None, openapi_url=None)
    app.state.store = store

    @app.middleware("http")
    async def limits_and_headers(request: Request, call_next):
        length = request.headers.get("content-length")
        if length is not None and (not length.isdigit() or int(length) > max_body_bytes):
            resp = JSONResponse({"error": "request body too large"}, status_code=413)
        else:
            resp = await call_next(request)
        for k, v in SECURITY_HEADERS.items():
            resp.headers.setdefault(k, v)
        return resp

    def participant_or_error(token: str | None):
        if not token:
            return None, JSONResponse({"error": "participant token missing"}, status_code=401)
        p = store.participant(token)
        if p is None:
            return None, JSONResponse({"error": "unknown participant token"}, status_code=403)
        return p, None

    def page_participant(token: str):
        p = store.participant(token)
        if p is None:
            return None, HTMLResponse(_page("Not found", "<p>This study link is not valid.</p>"), status_code=403)
        return p, None

    @app.get("/", response_class=HTMLResponse)
    def consent():
        text = consent_text or (
            "You will watch short videos of two animated people talking. Each video shows the same conversation twice, "
            "side by side, with the body motion made in two different ways. After each video you choose the side whose "
            "motion looks more natural. The study takes about 20 minutes. Your answers are stored without your name; you "
            "may stop at any time, and resume later with the link of your study page.")
        body = (f"<h1>{html.escape(title)}</h1><h2>Consent</h2><p>{html.escape(text)}</p>"
                f"<form method=post action='{R}/start'><button type=submit id=consent>I agree, start the study</button></form>"
                f"<h3>Resume</h3><form method=get action='{R}/resume'><input name=token id=resume-token aria-label='token'>"
                "<button type=submit id=resume>Resume</button></form>")
        return _page(title, body)

    @app.post("/start")
    def start():
        p = store.create_participant(lambda counts, index: design.choose_trials(stimulus_list, counts, n_trials, n_attention,
                                                                              seed, index))
        return RedirectResponse(f"{R}/p/{p.token}/instructions", status_code=303)

    @app.get("/resume")
    def resume(token: str = ""):
        if not re.fullmatch(r"[A-Za-z0-9_-]{8,64}", token or "") or store.participant(token) is None:
            return HTMLResponse(_page("Not found", "<p>No study with this token.</p>"), status_code=403)
        return RedirectResponse(f"{R}/p/{token}/trial", status_code=303)

    @app.get("/p/{token}/instructions", response_class=HTMLResponse)
    def instructions(token: str):
        p, err = page_participant(token)
        if err:
            return err
        body = ("<h1>Instructions</h1><p>Press <b>Play</b> and watch each video to its end with the sound on. Both halves "
                "show the same conversation. Then choose the side (left or right) whose body motion looks more natural. "
                f"There are {len(p.trials)} videos. Keep this page's address to resume later: "
                f"<code id=token>{html.escape(token)}</code></p>"
                f"<p><a id=begin href='{R}/p/{html.escape(token)}/trial'>Begin</a></p>")
        return _page(title, body)

    @app.get("/p/{token}", response_class=HTMLResponse)
    def participant_home(token: str):
        p, err = page_participant(token)
        if err:
            return err
        return RedirectResponse(f"{R}/p/{token}/trial", status_code=303)

    @app.get("/p/{token}/trial", response_class=HTMLResponse)
    def trial_page(token: str):
        p, err = page_participant(token)
        if err:
            return err
        done = store.answered(token)
        nxt = next((i for i in range(len(p.trials)) if i not in done), None)
        if nxt is None:
            return RedirectResponse(f"{R}/p/{token}/done", status_code=303)
        s = stimuli[p.trials[nxt]]
        pct = 100.0 * len(done) / len(p.trials)
        body = (f"<div class=progress><div style='width:{pct:.1f}%'></div></div>"
                f"<p id=progress>Video {nxt + 1} of {len(p.trials)}</p>"
                f"<video id=stimulus preload=auto playsinline src='{R}/media/{html.escape(Path(s['file']).name)}'></video>"
                "<p><button class=play id=play>Play</button> <span id=status>Watch the whole video, then choose.</span></p>"
                "<div class=choices><button id=choose-left data-side=left disabled>Left looks more natural</button>"
                "<button id=choose-right data-side=right disabled>Right looks more natural</button></div>"
                f"<script src='{R}/static/trial.js'></script>")
        return _page(title, body, {"token": token, "trial": nxt, "root": R})

    @app.get("/p/{token}/done", response_class=HTMLResponse)
    def done_page(token: str):
        p, err = page_participant(token)
        if err:
            return err
        if len(store.answered(token)) < len(p.trials):
            return RedirectResponse(f"{R}/p/{token}/trial", status_code=303)
        code = store.complete(token)
        return _page(title, f"<h1>Thank you</h1><p>Your completion code: <b id=code>{html.escape(code)}</b></p>")

    @app.get("/static/trial.js")
    def trial_js():
        return Response(TRIAL_JS, media_type="text/javascript")

    @app.get("/media/{name}")
    def media_file(name: str):
        if not MEDIA_NAME.fullmatch(name) or name not in media:
            return PlainTextResponse("not found", status_code=404)
        path = media[name].resolve()
        if not path.is_relative_to(study_dir) or not path.is_file():
            return PlainTextResponse("not found", status_code=404)
        return FileResponse(path, media_type="video/mp4")

    @app.post("/api/answer")
    async def answer(request: Request):
        p, err = await run_in_threadpool(participant_or_error, request.headers.get("x-participant-token"))
        if err:
            return err
        raw = b""
        async for chunk in request.stream():
            raw += chunk
            if len(raw) > max_body_bytes:
                return JSONResponse({"error": "request body too large"}, status_code=413)
        try:
            data = json.loads(raw)
        except (json.JSONDecodeError, UnicodeDecodeError):
            return JSONResponse({"error": "malformed JSON"}, status_code=400)
        if not isinstance(data, dict) or set(data) != {"trial", "side", "response_ms"}:
            return JSONResponse({"error": "expected exactly the fields trial, side, response_ms"}, status_code=422)
        trial, side, rt = data["trial"], data["side"], data["response_ms"]
        if type(trial) is not int or type(rt) is not int or side not in ("left", "right") or not 0 <= rt <= 3_600_000:
            return JSONResponse({"error": "trial and response_ms must be integers (0 <= response_ms <= 3600000), "
                                          "side 'left' or 'right'"}, status_code=422)
        if not 0 <= trial < len(p.trials):
            return JSONResponse({"error": f"no trial {trial} for this participant"}, status_code=404)
        stim = stimuli[p.trials[trial]]
        try:
            row, inserted = await run_in_threadpool(store.record_answer, p.token, trial, stim["id"], side, str(stim[side]), rt)
        except AnswerConflict as e:
            return JSONResponse({"error": e.reason}, status_code=409)
        answered = len(await run_in_threadpool(store.answered, p.token))
        return {"stored": inserted, "trial": trial, "answered": answered, "total": len(p.trials),
                "finished": answered == len(p.trials)}

    @app.get("/api/me")
    def me(request: Request):
        p, err = participant_or_error(request.headers.get("x-participant-token"))
        if err:
            return err
        done = store.answered(p.token)
        return {"total": len(p.trials), "answered": len(done),
                "answers": [{"trial": t, "chosen_side": r["chosen_side"]} for t, r in sorted(done.items())]}

    @app.get("/admin/export.csv")
    def export(request: Request):
        auth = request.headers.get("authorization", "")
        if not auth:
            return PlainTextResponse("admin token missing", status_code=401, headers={"WWW-Authenticate": "Bearer"})
        given = auth[7:] if auth.lower().startswith("bearer ") else ""
        if not admin_token or not hmac.compare_digest(given.encode(), str(admin_token).encode()):
            return PlainTextResponse("forbidden", status_code=403)
        buf = io.StringIO()
        w = csv.DictWriter(buf, fieldnames=EXPORT_COLUMNS, lineterminator="\n")
        w.writeheader()
        for r in store.answers():
            s = stimuli.get(r["stimulus"], {})
            w.writerow({**{k: s.get(k) for k in EXPORT_COLUMNS}, **r})
        return Response(buf.getvalue(), media_type="text/csv")

    @app.get("/healthz")
    def health():
        return {"ok": True, **store.counts()}

    return app
