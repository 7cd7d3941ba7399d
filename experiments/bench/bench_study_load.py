"""Load benchmark of the study server (docs/study.md): N simulated participants (default 50) sign up
at once and each answer their 20 trials plus 2 attention checks concurrently, against a real uvicorn
process on a loopback port (SQLite in WAL mode, synchronous=FULL). Each participant also fetches
its trial page before every answer and re-sends one answer (idempotency). Afterwards the admin
export must hold exactly one row per acknowledged answer: 0 lost, 0 duplicated.

    python experiments/bench/bench_study_load.py [--participants 50] [--trials 20]

Writes experiments/results/bench_study_load.json (+ manifest): latencies (p50/p95/max, ms) per
request kind, throughput, counts. The study folder is a made-up one (convsynth_jax.testing.study:
tiny real H.264 videos, 20 segments x the paper's 4 pairs); the server does not read the videos
except for the one fetch per participant."""
import argparse
import asyncio
import csv
import io
import os
import signal
import tempfile
import time
from pathlib import Path


import numpy as np

from convsynth_jax.study import design
from convsynth_jax.testing.study import make_fake_study, serve_subprocess
from convsynth_jax.testing.web import free_port
from convsynth_jax.api import write_result

ADMIN = "bench-admin-token-0123456789abcdef"


async def participant(client, k: int, lat: dict, acked: list, total_expected: int):
    import httpx  # noqa: F401

    def rec(kind, t0):
        lat.setdefault(kind, []).append(1000 * (time.perf_counter() - t0))

    t0 = time.perf_counter()
    r = await client.post("/start", follow_redirects=False)
    rec("start", t0)
    token = r.headers["location"].split("/p/")[1].split("/")[0]
    h = {"X-Participant-Token": token}
    t0 = time.perf_counter()
    me = (await client.get("/api/me", headers=h)).json()
    rec("me", t0)
    total = me["total"]
    assert total == total_expected, me
    first_media = None
    for i in range(total):
        t0 = time.perf_counter()
        page = await client.get(f"/p/{token}/trial")
        rec("trial_page", t0)
        if first_media is None:
            first_media = page.text.split("/media/")[1].split("'")[0]
            t0 = time.perf_counter()
            await client.get(f"/media/{first_media}")
            rec("media", t0)
        body = {"trial": i, "side": "left" if (i + k) % 2 else "right", "response_ms": 700 + i}
        t0 = time.perf_counter()
        a = await client.post("/api/answer", json=body, headers=h)
        rec("answer", t0)
        if a.status_code == 200:
            acked.append((token, i))
        if i == total // 2:      # one re-sent answer per participant: stored once
            t0 = time.perf_counter()
            again = await client.post("/api/answer", json=body, headers=h)
            rec("answer_resent", t0)
            assert again.status_code == 200 and again.json()["stored"] is False, again.text
    t0 = time.perf_counter()
    await client.get(f"/p/{token}/done")
    rec("done_page", t0)


async def main_async(base: str, n: int, total: int):
    import httpx

    lat, acked = {}, []
    limits = httpx.Limits(max_connections=n, max_keepalive_connections=n)
    async with httpx.AsyncClient(base_url=base, timeout=120.0, limits=limits) as client:
        t0 = time.perf_counter()
        await asyncio.gather(*(participant(client, k, lat, acked, total) for k in range(n)))
        wall = time.perf_counter() - t0
    return lat, acked, wall


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--participants", type=int, default=50)
    ap.add_argument("--trials", type=int, default=20)
    ap.add_argument("--attention", type=int, default=2)
    args = ap.parse_args()
    import httpx

    with tempfile.TemporaryDirectory() as tmp:
        study = Path(tmp) / "study"
        t0 = time.perf_counter()
        make_fake_study(study, segments=20, pairs=design.PAPER_PAIRS, attention=args.attention,
                        trials_per_participant=args.trials, attention_per_participant=args.attention)
        t_build = time.perf_counter() - t0
        port = free_port()
        load_before = os.getloadavg()
        proc = serve_subprocess(study, Path(tmp) / "answers.sqlite", port, ADMIN)
        base = f"http://127.0.0.1:{port}"
        try:
            lat, acked, wall = asyncio.run(main_async(base, args.participants, args.trials + args.attention))
            export = httpx.get(base + "/admin/export.csv", headers={"Authorization": f"Bearer {ADMIN}"}, timeout=60).text
        finally:
            os.kill(proc.pid, signal.SIGTERM)
            proc.wait(timeout=30)
        load_after = os.getloadavg()
    rows = list(csv.DictReader(io.StringIO(export)))
    keys = [(r["participant"], int(r["trial"])) for r in rows]
    lost = len(set(acked) - set(keys))
    dup = len(keys) - len(set(keys))
    pct = {k: {"n": len(v), "p50_ms": float(np.percentile(v, 50)), "p95_ms": float(np.percentile(v, 95)),
               "max_ms": float(np.max(v))} for k, v in sorted(lat.items())}
    result = {
        "participants": args.participants, "trials_per_participant": args.trials, "attention_per_participant": args.attention,
        "answers_expected": args.participants * (args.trials + args.attention), "answers_acknowledged": len(acked),
        "answers_exported": len(rows), "lost": lost, "duplicated": dup, "wall_s": wall,
        "answers_per_s": len(acked) / wall, "latency": pct, "fake_study_build_s": t_build,
        "loadavg_before": list(load_before), "loadavg_after": list(load_after), "cpu_count": os.cpu_count(),
    }
    write_result("bench_study_load", result)
    if lost or dup or len(acked) != result["answers_expected"]:
        raise SystemExit("answers lost or duplicated")


if __name__ == "__main__":
    main()
