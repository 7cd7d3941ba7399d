"""Test helpers of the study kit: a small study folder without synthesis (its stimuli are real H.264
videos of made-up bodies), for the server tests and the load benchmark; and a scripted participant
that answers through the HTTP API."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..study import design
from ..study.build import MANIFEST_COLUMNS, sha256_of
from ..render import DrawnBody, render_pair_video
from ..utils import write_json_atomic


def _stick_body(offset: float, frames: int, phase: float) -> DrawnBody:
    """A five-joint body (hips, chest, head, two hands) waving one hand; Y up, 1.7 units tall."""
    t = np.arange(frames)[:, None]
    base = np.array([[0, 0.9, 0], [0, 1.4, 0], [0, 1.7, 0], [0.3, 1.1, 0.1], [-0.3, 1.1, 0.1]], np.float32)
    pos = np.repeat(base[None], frames, axis=0)
    pos[:, 3, 1] += 0.2 * np.sin(0.4 * t[:, 0] + phase)
    pos[..., 0] += offset
    return DrawnBody(pos, (-1, 0, 1, 1, 1), 2, (3, 4), frozenset({0, 1, 2}))


def make_fake_study(out: str | Path, segments: int = 3, pairs=design.PAPER_PAIRS[:2], attention: int = 1, seed: int = 0,
                    trials_per_participant: int = 4, attention_per_participant: int = 1, frames: int = 6,
                    fps: float = 30.0) -> dict:
    """A study folder as ``study_build`` writes it (manifest.json, manifest.csv, media/*.mp4) whose
    videos show made-up bodies (``frames`` frames, 64 x 64 panels, no audio)."""
    import pandas as pd

    out = Path(out)
    segs = [{"segment": k, "session": "fake", "fold": 0, "window": k, "window_start": 15.0 * k,
             "window_end": 15.0 * k + 15.0, "seeds": {}} for k in range(segments)]
    stimuli = design.plan_stimuli(segs, pairs, attention, seed)
    records = []
    for s in stimuli:
        rel = f"media/{s['id']}.mp4"
        left = [_stick_body(-0.6, frames, 0.0), _stick_body(0.6, frames, 1.0)]
        right = [_stick_body(-0.6, frames, 2.0), _stick_body(0.6, frames, 3.0)]
        p = render_pair_video(left, right, fps, out / rel, width=64, height=64, render_fps=fps)
        records.append({**{k: s.get(k) for k in MANIFEST_COLUMNS if k in s}, "file": rel, "sha256": sha256_of(p),
                        "bytes": p.stat().st_size})
    manifest = {"study": {"seed": seed, "system": "fake", "fps": fps, "pairs": [vars(p) for p in pairs],
                          "segments": segments, "attention_stimuli": attention, "repetitions": 10,
                          "trials_per_participant": trials_per_participant,
                          "attention_per_participant": attention_per_participant},
                "stimuli": records, "rejected_windows": [], "timings": {}}
    pd.DataFrame(records).to_csv(out / "manifest.csv", index=False)
    write_json_atomic(out / "manifest.json", manifest)
    return manifest


def answer_all(client, token: str, total: int, choose=lambda i: "left", start: int = 0, stop: int | None = None) -> list:
    """POST answers for trials ``start``..``stop`` (default: all) through ``client`` (an httpx or
    Starlette TestClient bound to the server); returns the responses."""
    out = []
    for i in range(start, total if stop is None else stop):
        out.append(client.post("/api/answer", json={"trial": i, "side": choose(i), "response_ms": 500 + i},
                               headers={"X-Participant-Token": token}))
    return out


def sign_up(client) -> str:
    """A new participant's token (POST /start, the token read from the redirect)."""
    r = client.post("/start", follow_redirects=False)
    if r.status_code != 303:
        raise RuntimeError(f"/start answered {r.status_code}")
    return r.headers["location"].split("/p/")[1].split("/")[0]


def serve_subprocess(study, db, port: int, admin_token: str, extra: str = ""):
    """A uvicorn process serving ``study`` on 127.0.0.1:``port`` (its own session, so the caller
    can SIGKILL it alone); returns the Popen once /healthz answers."""
    import subprocess
    import sys
    import time

    import httpx

    code = ("import sys, uvicorn; from convsynth_jax.study.server import create_app; "
            f"uvicorn.run(create_app(sys.argv[1], sys.argv[2], admin_token={admin_token!r}{extra}), host='127.0.0.1', "
            f"port={int(port)}, log_level='error')")
    p = subprocess.Popen([sys.executable, "-c", code, str(study), str(db)], start_new_session=True)
    for _ in range(600):
        if p.poll() is not None:
            raise RuntimeError(f"the study server exited with {p.returncode}")
        try:
            if httpx.get(f"http://127.0.0.1:{port}/healthz", timeout=1.0).status_code == 200:
                return p
        except httpx.HTTPError:
            time.sleep(0.1)
    p.kill()
    raise RuntimeError("the study server did not start within 60 s")
