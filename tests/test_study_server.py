"""The study kit without a browser: design (balance, assignment), the store, the web application's
flow and its security and reliability cases (Starlette's TestClient; the SIGKILL case with a real
uvicorn process on a loopback port), and the analysis of exported answers."""
from __future__ import annotations

import csv
import io
import os
import signal
import sqlite3

import numpy as np
import pandas as pd
import pytest

from convsynth_jax.errors import ConfigError, FormatError
from convsynth_jax.study import design

pytest.importorskip("fastapi")
from fastapi.testclient import TestClient  # noqa: E402

from convsynth_jax.study.server import create_app  # noqa: E402
from convsynth_jax.testing.study import answer_all, make_fake_study, serve_subprocess, sign_up  # noqa: E402
from convsynth_jax.testing.web import free_port  # noqa: E402

ADMIN = "a-long-admin-token-0123456789"


@pytest.fixture(scope="module")
def fake_study(tmp_path_factory):
    d = tmp_path_factory.mktemp("fake_study")
    make_fake_study(d)
    return d


@pytest.fixture
def client(fake_study, tmp_path):
    app = create_app(fake_study, tmp_path / "answers.sqlite", admin_token=ADMIN)
    with TestClient(app) as c:
        yield c


def db_rows(client):
    return client.app.state.store.answers()


# ------------------------------------------------------------------------------------------ design
def test_sides_are_balanced_per_pair_and_attention_checks_expect_the_moving_side():
    segs = [{"segment": k} for k in range(5)]
    st = design.plan_stimuli(segs, design.PAPER_PAIRS, attention=3, seed=4)
    assert [s["id"] for s in st] == [f"s{i:03d}" for i in range(23)]
    for j, p in enumerate(design.PAPER_PAIRS):
        a_left = [s["left"] == p.a for s in st if s["pair"] == p.name]
        assert len(a_left) == 5 and sum(a_left) == (3, 2)[j % 2]   # ceil / floor of 5 / 2, alternating over pairs
    one = design.plan_stimuli(segs[:1], design.PAPER_PAIRS, attention=0, seed=4)
    assert sum(s["left"] == s["condition_a"] for s in one) == 2
    for s in st[-3:]:
        assert s["kind"] == "attention" and s[s["expected"]] == design.GROUND_TRUTH
        assert {s["left"], s["right"]} == {design.GROUND_TRUTH, design.FROZEN}
    assert design.plan_stimuli(segs, design.PAPER_PAIRS, 3, 4) == st


def test_trials_reach_their_repetitions_evenly():
    st = design.plan_stimuli([{"segment": k} for k in range(5)], design.PAPER_PAIRS, attention=2, seed=0)
    counts: dict = {}
    for i in range(design.participants_needed(st, repetitions=10, trials=20)):
        t = design.choose_trials(st, counts, 20, 2, seed=0, participant_index=i)
        assert len(t) == 22 and len(set(t)) == 22
        assert t[0] not in ("s020", "s021")                   # never starts with an attention check
        for s in t:
            counts[s] = counts.get(s, 0) + 1
    regular = [counts[s["id"]] for s in st if s["kind"] == "pair"]
    assert regular == [10] * 20


def test_pairs_from_config_errors():
    with pytest.raises(ConfigError, match="itself"):
        design.pairs_from_config([{"name": "x", "a": "all", "b": "all"}])
    with pytest.raises(ConfigError, match="lacks"):
        design.pairs_from_config([{"name": "x", "a": "all"}])
    with pytest.raises(ConfigError, match="distinct"):
        design.pairs_from_config([{"name": "x", "a": "all", "b": "none"}] * 2)


# ------------------------------------------------------------------------------------------ flow
def test_participant_flow_resume_idempotent_answers_and_completion_code(client):
    assert "I agree" in client.get("/").text
    tok = sign_up(client)
    total = client.get("/api/me", headers={"X-Participant-Token": tok}).json()["total"]
    assert total == 5                                          # 4 trials + 1 attention check
    page = client.get(f"/p/{tok}/trial")
    assert "Video 1 of 5" in page.text and "disabled" in page.text and "/media/s0" in page.text
    r = answer_all(client, tok, total, stop=2)
    assert all(x.status_code == 200 and x.json()["stored"] for x in r)
    again = answer_all(client, tok, total, stop=1)[0]          # the same answer re-sent: stored once
    assert again.status_code == 200 and again.json()["stored"] is False
    other = client.post("/api/answer", json={"trial": 0, "side": "right", "response_ms": 1}, headers={"X-Participant-Token": tok})
    assert other.status_code == 409                            # the first answer stands
    assert len(db_rows(client)) == 2 and db_rows(client)[0]["chosen_side"] == "left"
    assert "Video 3 of 5" in client.get(f"/p/{tok}").text      # resumption: the next unanswered trial
    assert client.get(f"/resume?token={tok}").url.path == f"/p/{tok}/trial"
    assert client.get(f"/p/{tok}/done").url.path == f"/p/{tok}/trial"   # no code before the end
    answer_all(client, tok, total, start=2)
    code = client.get(f"/p/{tok}/done")
    assert "completion code" in code.text
    assert client.get(f"/p/{tok}/done").text == code.text     # the same code every time
    rows = db_rows(client)
    assert [r["trial"] for r in rows] == list(range(5))
    man = client.app.state.store.participant(tok).trials
    assert [r["stimulus"] for r in rows] == list(man)


def test_export_needs_the_admin_token_and_holds_every_answer(client):
    tok = sign_up(client)
    answer_all(client, tok, 5, choose=lambda i: "right")
    assert client.get("/admin/export.csv").status_code == 401
    assert client.get("/admin/export.csv", headers={"Authorization": "Bearer wrong-token-xxxxxxxxxxxx"}).status_code == 403
    assert client.get("/admin/export.csv", headers={"Authorization": ADMIN}).status_code == 403
    r = client.get("/admin/export.csv", headers={"Authorization": f"Bearer {ADMIN}"})
    assert r.status_code == 200
    rows = list(csv.DictReader(io.StringIO(r.text)))
    assert len(rows) == 5 and {x["chosen_side"] for x in rows} == {"right"}
    assert all(x["chosen_condition"] == x["right"] for x in rows)


def test_export_disabled_without_an_admin_token(fake_study, tmp_path):
    with TestClient(create_app(fake_study, tmp_path / "db.sqlite")) as c:
        assert c.get("/admin/export.csv", headers={"Authorization": "Bearer "}).status_code == 403
        assert c.get("/admin/export.csv", headers={"Authorization": "Bearer None"}).status_code == 403


# ------------------------------------------------------------------------------------------ security
@pytest.mark.parametrize("path", [
    "/media/../manifest.json", "/media/%2e%2e/manifest.json", "/media/..%2fmanifest.json", "/media/%2e%2e%2fanswers.sqlite",
    "/media/s000.mp4%00.txt", "/media/manifest.json", "/media/s999.mp4", "/media/..%5cmanifest.json",
    "/media/%2fetc%2fpasswd", "/media//etc/passwd", "/media/s000.MP4",
])
def test_media_only_from_the_study_folder(client, path):
    r = client.get(path)
    assert r.status_code in (400, 404) and b"stimuli" not in r.content and b"root:" not in r.content


def test_media_is_served_with_range_requests(client):
    r = client.get("/media/s000.mp4")
    assert r.status_code == 200 and r.headers["content-type"] == "video/mp4" and r.content[4:8] == b"ftyp"
    part = client.get("/media/s000.mp4", headers={"Range": "bytes=0-99"})
    assert part.status_code == 206 and len(part.content) == 100


def test_tokens_missing_or_forged_are_refused(client):
    body = {"trial": 0, "side": "left", "response_ms": 10}
    assert client.post("/api/answer", json=body).status_code == 401
    assert client.post("/api/answer", json=body, headers={"X-Participant-Token": "forged-token-abcdefgh"}).status_code == 403
    assert client.get("/api/me").status_code == 401
    assert client.get("/p/forged-token-abcdefgh/trial").status_code == 403
    assert client.get("/resume?token=../../etc").status_code == 403
    assert db_rows(client) == []


def test_a_participant_cannot_read_or_change_anothers_answers(client):
    a, b = sign_up(client), sign_up(client)
    answer_all(client, b, 5, choose=lambda i: "left")
    before = db_rows(client)
    answer_all(client, a, 5, choose=lambda i: "right")          # A's trial indices are A's own
    mine = client.get("/api/me", headers={"X-Participant-Token": a}).json()
    assert mine["answered"] == 5 and {x["chosen_side"] for x in mine["answers"]} == {"right"}
    after = db_rows(client)
    assert [r for r in after if r["participant"] == b] == before
    assert "participant" not in str(mine)                       # nothing about anyone else
    # a token in the body or a query does not act for another participant
    r = client.post("/api/answer", json={"trial": 0, "side": "right", "response_ms": 1, "participant": b},
                    headers={"X-Participant-Token": a})
    assert r.status_code == 422


@pytest.mark.parametrize("body,status", [
    (b"{" * 10, 400), (b"not json", 400), (b"\xff\xfe", 400), (b"[1, 2]", 422), (b"null", 422),
    (b'{"trial": 0, "side": "left"}', 422),
    (b'{"trial": "0", "side": "left", "response_ms": 1}', 422),
    (b'{"trial": 0.0, "side": "left", "response_ms": 1}', 422),
    (b'{"trial": true, "side": "left", "response_ms": 1}', 422),
    (b'{"trial": 0, "side": "left\'; DROP TABLE answers; --", "response_ms": 1}', 422),
    (b'{"trial": 0, "side": "left", "response_ms": "1); DELETE FROM answers; --"}', 422),
    (b'{"trial": 0, "side": "left", "response_ms": -5}', 422),
    (b'{"trial": 99, "side": "left", "response_ms": 1}', 404),
    (b'{"trial": -1, "side": "left", "response_ms": 1}', 404),
    (b'{"trial": 0, "side": "left", "response_ms": 1, "x": "' + b"a" * 4000 + b'"}', 413),
])
def test_malformed_oversized_and_sql_like_payloads_leave_the_database_unchanged(client, body, status):
    tok = sign_up(client)
    answer_all(client, tok, 5, stop=1)
    con = sqlite3.connect(client.app.state.store.path)
    dump = list(con.iterdump())
    r = client.post("/api/answer", content=body, headers={"X-Participant-Token": tok, "Content-Type": "application/json"})
    assert r.status_code == status
    assert list(con.iterdump()) == dump
    con.close()


def test_a_chunked_body_over_the_limit_is_refused(client):
    tok = sign_up(client)

    def chunks():
        for _ in range(10):
            yield b" " * 500

    r = client.post("/api/answer", content=chunks(), headers={"X-Participant-Token": tok})
    assert r.status_code == 413 and db_rows(client) == []


def test_security_headers(client):
    h = client.get("/").headers
    assert h["x-content-type-options"] == "nosniff" and h["referrer-policy"] == "no-referrer"
    assert "script-src 'self'" in h["content-security-policy"]


# ------------------------------------------------------------------------------------------ SIGKILL
def _serve(study, db, port):
    return serve_subprocess(study, db, port, ADMIN)


def test_server_killed_with_sigkill_loses_no_acknowledged_answer(fake_study, tmp_path):
    import httpx

    db, port = tmp_path / "answers.sqlite", free_port()
    proc = _serve(fake_study, db, port)
    acked = []
    try:
        with httpx.Client(base_url=f"http://127.0.0.1:{port}") as c:
            toks = [sign_up(c) for _ in range(3)]
            for i in range(3):                                      # 3 of each participant's 5 trials
                for t in toks:
                    r = c.post("/api/answer", json={"trial": i, "side": "left", "response_ms": i},
                               headers={"X-Participant-Token": t})
                    if r.status_code == 200:
                        acked.append((t, i))
            os.kill(proc.pid, signal.SIGKILL)                       # mid-study: nobody has finished
    finally:
        proc.kill()
        proc.wait()
    assert len(acked) == 9
    proc = _serve(fake_study, db, port)
    try:
        with httpx.Client(base_url=f"http://127.0.0.1:{port}") as c:
            r = c.get("/admin/export.csv", headers={"Authorization": f"Bearer {ADMIN}"})
            got = {(x["participant"], int(x["trial"])) for x in csv.DictReader(io.StringIO(r.text))}
            assert got == set(acked)
            assert c.get(f"/p/{toks[0]}/trial").status_code == 200  # resumption after the restart
    finally:
        os.kill(proc.pid, signal.SIGTERM)
        proc.wait(timeout=30)


# ------------------------------------------------------------------------------------------ analysis
def _export(client):
    return pd.read_csv(io.StringIO(client.get("/admin/export.csv", headers={"Authorization": f"Bearer {ADMIN}"}).text),
                       dtype={"expected": str})


def test_analysis_counts_clicks_and_excludes_attention_failures(client, fake_study):
    from convsynth_jax.study.analyze import analyze_answers
    from convsynth_jax.study.build import load_study_manifest

    stim = {s["id"]: s for s in load_study_manifest(fake_study)["stimuli"]}
    store = client.app.state.store
    toks = [sign_up(client) for _ in range(3)]
    expected = {p.name: [0, 0] for p in design.PAPER_PAIRS[:2]}
    for k, t in enumerate(toks):
        trials = store.participant(t).trials
        for i, sid in enumerate(trials):
            s = stim[sid]
            if s["kind"] == "attention":
                side = s["expected"] if k < 2 else ("left" if s["expected"] == "right" else "right")   # the third fails
            else:
                side = "left" if (i + k) % 3 else "right"
                if k < 2:
                    expected[s["pair"]][0] += s[side] == s["condition_a"]
                    expected[s["pair"]][1] += 1
            client.post("/api/answer", json={"trial": i, "side": side, "response_ms": 1}, headers={"X-Participant-Token": t})
    table, att = analyze_answers(_export(client), design.PAPER_PAIRS[:2])
    assert att["excluded"].tolist() == [p == toks[2] for p in att["participant"]]
    got = {r.pair: [r.preferred_a, r.total] for r in table.itertuples()}
    assert got == expected


def test_forced_choice_table_reproduces_the_papers_tests():
    from convsynth_jax.study.analyze import forced_choice_table
    from convsynth_jax.tasks.user_study import PAPER_CSV

    t = forced_choice_table(pd.read_csv(PAPER_CSV))
    assert np.allclose(t["chi2"], [57.563, 5.0155, 1.4328, 9.61], atol=2e-3)   # paper Section 8.2
    assert t["significant"].tolist() == [True, True, False, True]
    assert (t["binom_p"] > 0).all() and (t["share_ci_low"] < t["share_a"]).all()


def test_read_answers_names_the_bad_line(tmp_path):
    from convsynth_jax.study.analyze import ANSWER_FIELDS, read_answers

    rows = [dict.fromkeys(ANSWER_FIELDS, "x") | {"trial": 0, "chosen_side": "left"},
            dict.fromkeys(ANSWER_FIELDS, "x") | {"trial": 1, "chosen_side": "up"}]
    pd.DataFrame(rows).to_csv(tmp_path / "a.csv", index=False)
    with pytest.raises(FormatError, match="line 3"):
        read_answers(tmp_path / "a.csv")


def test_study_serve_settings(fake_study, monkeypatch):
    from convsynth_jax.tasks.study_serve import StudyServeSettings, make_app

    with pytest.raises(ConfigError, match="task.study"):
        make_app(StudyServeSettings())
    with pytest.raises(ConfigError, match="16 characters"):
        make_app(StudyServeSettings(study=str(fake_study), admin_token="short"))
    monkeypatch.setenv("CONVSYNTH_STUDY_ADMIN_TOKEN", ADMIN)
    app, db, export = make_app(StudyServeSettings(study=str(fake_study), db=str(fake_study.parent / "serve.sqlite"),
                                                  root_path="/study"))
    assert export and db.name == "serve.sqlite"
    with TestClient(app) as c:
        assert "action='/study/start'" in c.get("/").text
        assert c.post("/start", follow_redirects=False).headers["location"].startswith("/study/p/")
        assert c.get("/admin/export.csv", headers={"Authorization": f"Bearer {ADMIN}"}).status_code == 200
