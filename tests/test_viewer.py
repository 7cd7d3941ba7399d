"""The 3D viewer (``task=view``, convsynth_jax/viewer): the scene Python computes (joint positions
against hand-computed forward kinematics, labels, audio ownership), the server's refusals (path
traversal, unknown names, a malformed input shown as an error), the static export, and a real
headless Chromium (skipped without Chromium and chromedriver): both characters drawn where they
stand, two times differ, the timeline cursor follows the audio clock, nothing loaded from outside,
the export drawn from file://.

The fixture is two made-up characters written here: seven-joint BVHs (10 s at 10 fps) seated 120
units apart facing each other, waving the left arm, with a WAV each and a synthesize-like report."""
from __future__ import annotations

import json
import shutil
import socket
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("starlette")

FPS, FRAMES = 10, 100
JOINTS = ("Hips", "Spine", "Head", "LeftArm", "LeftHand", "RightArm", "RightHand")


def write_bvh(path: Path, z: float, yaw: float, phase: float) -> None:
    """A seven-joint character at (0, 90, z) turned by ``yaw`` degrees, its left arm waving about Z."""
    from convsynth_jax.io import save_bvh
    from convsynth_jax.rotations import euler_deg_to_quat_np
    from convsynth_jax.skeleton import Motion, Skeleton

    rot = ("Zrotation", "Xrotation", "Yrotation")
    offsets = np.array([[0, 0, 0], [0, 20, 0], [0, 25, 0], [15, 20, 0], [0, -30, 0], [-15, 20, 0], [0, -30, 0]], float)
    skel = Skeleton(JOINTS, (-1, 0, 1, 1, 3, 1, 5), offsets, (("Xposition", "Yposition", "Zposition") + rot,) + (rot,) * 6,
                    ((2, (0.0, 10.0, 0.0)), (4, (0.0, -5.0, 0.0)), (6, (0.0, -5.0, 0.0))))
    euler = np.zeros((FRAMES, len(JOINTS), 3))                       # (Z, X, Y) degrees, the channels' order
    euler[:, 0, 2] = yaw
    euler[:, 3, 0] = 150.0 * (0.5 + 0.5 * np.sin(2 * np.pi * np.arange(FRAMES) / FRAMES + phase))   # the left arm swings
    euler[:, 5, 0] = -10.0
    trans = np.broadcast_to(offsets, (FRAMES, len(JOINTS), 3)).copy()
    trans[:, 0] = [0.0, 90.0, z]
    save_bvh(Motion(skel, euler_deg_to_quat_np(euler, "ZXY"), trans, float(FPS)), path, precision=4)


def write_wav(path: Path, seconds: float, hz: float) -> None:
    from convsynth_jax.io import save_wav

    t = np.arange(int(seconds * 8000)) / 8000.0
    save_wav(path, 0.2 * np.sin(2 * np.pi * hz * t), 8000)


@pytest.fixture(scope="module")
def out(tmp_path_factory):
    """A folder laid out as task=synthesize writes it."""
    d = tmp_path_factory.mktemp("viewer") / "synth_out"
    d.mkdir()
    write_bvh(d / "alice.bvh", -60.0, 0.0, 0.0)
    write_bvh(d / "bob.bvh", 60.0, 180.0, 2.0)
    write_wav(d / "speaker_input.wav", 10.0, 220.0)
    write_wav(d / "listener_input.wav", 10.0, 330.0)
    rep = {"characters": {
        "alice": {"success": True, "role": "speaker", "transitions": [{"frame": 20}, {"frame": 55}],
                  "checker": {"details": [{"kind": "PC", "start": 10, "end": 30, "met": True},
                                          {"kind": "LR", "start": 40, "end": 45, "met": True},
                                          {"kind": "PH", "start": 60, "end": 70, "met": True},
                                          {"kind": "idle", "start": 0, "end": 10, "met": True}]}},
        "bob": {"success": True, "role": "listener", "transitions": [{"frame": 33}], "checker": {"details": []}}}}
    (d / "report.json").write_text(json.dumps(rep))
    (d / "notes.txt").write_text("not served")
    return d


@pytest.fixture(scope="module")
def broken(tmp_path_factory):
    d = tmp_path_factory.mktemp("viewer_bad")
    write_bvh(d / "x.bvh", 0.0, 0.0, 0.0)
    text = (d / "x.bvh").read_text().splitlines()
    text[-3] = "0 90 0 zero 0 0"                                   # a non-numeric channel value
    (d / "x.bvh").write_text("\n".join(text) + "\n")
    return d


# ------------------------------------------------------------------------------------------ the scene
def test_scene_positions_labels_audio_and_transitions(out):
    from convsynth_jax.viewer.scene import load_scene

    s = load_scene(out)
    assert [c["name"] for c in s["characters"]] == ["alice", "bob"] and s["duration"] == pytest.approx(10.0)
    a, b = s["characters"]
    assert a["joints"] == 7 and a["frames"] == FRAMES and a["fps"] == FPS
    P = np.asarray(a["positions"], np.float64).reshape(FRAMES, a["joints"], 3) * s["scale"]
    names = a["joint_names"]
    # hand-computed forward kinematics: no rotation along the root-spine-head chain
    assert np.allclose(P[:, names.index("Head")], [0, 90 + 20 + 25, -60], atol=0.05)
    assert np.allclose(P[:, names.index("RightArm")], [-15, 90 + 20 + 20, -60], atol=0.05)
    # the left hand on a circle of radius 30 about the shoulder (Z rotation by the wave angle)
    w = np.radians(150.0 * (0.5 + 0.5 * np.sin(2 * np.pi * np.arange(FRAMES) / FRAMES)))
    want = np.stack([15 + 30 * np.sin(w), 130 - 30 * np.cos(w), np.full(FRAMES, -60.0)], axis=1)
    assert np.allclose(P[:, names.index("LeftHand")], want, atol=0.05)
    Pb = np.asarray(b["positions"], np.float64).reshape(FRAMES, b["joints"], 3) * s["scale"]
    assert np.allclose(Pb[0, names.index("RightArm")], [15, 130, 60], atol=0.05)   # turned to face alice
    assert [names[i] for i in a["hands"]] == ["LeftHand", "RightHand"] and names[a["head"]] == "Head"
    assert sorted(tuple(x) for x in a["bones"]) == sorted([(0, 1), (1, 2), (1, 3), (3, 4), (1, 5), (5, 6)])
    assert a["labels"] == [{"kind": "PC", "start": 1.0, "end": 3.0}, {"kind": "LR", "start": 4.0, "end": 4.5}]
    assert b["labels"] == [{"kind": "HP", "start": 6.0, "end": 7.0}]     # alice's PH is bob's hesitation
    assert a["transitions"] == [2.0, 5.5] and b["transitions"] == [3.3]
    owners = {t["name"]: t["character"] for t in s["audio"]}
    assert owners == {"speaker_input.wav": "alice", "listener_input.wav": "bob"}


def test_scene_segments_of_the_report_win_and_task_audio_replaces(out, tmp_path):
    from convsynth_jax.viewer.scene import load_scene

    d = tmp_path / "conv"
    shutil.copytree(out, d)
    (d / "report.json").write_text(json.dumps({"segments": {"alice": [{"kind": "HP", "start": 0.5, "end": 1.5}],
                                                             "bob": [{"kind": "LR", "start": 2, "end": 3}]}}))
    s = load_scene(d, audio=[str(d / "speaker_input.wav")])
    assert s["characters"][0]["labels"] == [{"kind": "HP", "start": 0.5, "end": 1.5}]
    assert s["characters"][1]["labels"] == [{"kind": "LR", "start": 2.0, "end": 3.0}]
    assert [t["name"] for t in s["audio"]] == ["speaker_input.wav"]


def test_bad_inputs_name_the_file(broken, tmp_path, out):
    from convsynth_jax.errors import FormatError, MissingFileError
    from convsynth_jax.viewer.scene import load_scene, try_load_scene

    with pytest.raises(FormatError, match="x.bvh"):
        load_scene(broken)
    with pytest.raises(MissingFileError, match="nothing.bvh"):
        load_scene(tmp_path / "nothing.bvh")
    with pytest.raises(MissingFileError, match="gone.wav"):
        load_scene(out, audio=str(tmp_path / "gone.wav"))
    (tmp_path / "bad.wav").write_bytes(b"RIFF0000WAVEjunk")
    with pytest.raises(FormatError, match="bad.wav"):
        load_scene(out, audio=str(tmp_path / "bad.wav"))
    assert "x.bvh" in try_load_scene(broken)["error"]


# ------------------------------------------------------------------------------------------ the server
def test_server_serves_the_scene_and_only_its_files(out):
    from starlette.testclient import TestClient

    from convsynth_jax.viewer.server import create_viewer_app

    c = TestClient(create_viewer_app(out))
    r = c.get("/")
    assert r.status_code == 200 and "scene.js" in r.text and "three.bundle.min.js" in r.text
    assert "default-src 'self'" in r.headers["content-security-policy"]
    js = c.get("/scene.js").text
    scene = json.loads(js[js.index("=") + 1:].strip().rstrip(";"))
    assert {t["url"] for t in scene["audio"]} == {"files/speaker_input.wav", "files/listener_input.wav"}
    assert str(out) not in js                                     # no paths on disk in the page
    assert c.get("/files/speaker_input.wav").content[:4] == b"RIFF"
    assert c.get("/three.bundle.min.js").status_code == 200 and c.get("/viewer.js").status_code == 200
    for probe in ("/files/alice.bvh", "/files/report.json", "/files/notes.txt", "/files/..%2freport.json",
                  "/files/%2e%2e%2f%2e%2e%2fetc%2fpasswd", "/scene.py", "/server.py", "/vendor/three_entry.js",
                  "/files/", "/static/viewer.js"):
        assert c.get(probe).status_code == 404, probe


def test_server_shows_a_malformed_input_as_an_error_scene(broken, caplog):
    from starlette.testclient import TestClient

    from convsynth_jax.viewer.server import create_viewer_app

    c = TestClient(create_viewer_app(broken))
    with caplog.at_level("ERROR"):
        js = c.get("/scene.js").text
    assert '"error"' in js and "x.bvh" in js and "x.bvh" in caplog.text
    assert c.get("/healthz").json() == {"ok": False}


def test_export_writes_a_whole_folder_and_refuses_bad_input(out, broken, tmp_path):
    from convsynth_jax.config import compose, run_task
    from convsynth_jax.errors import FormatError
    from convsynth_jax.viewer.server import export

    summary = run_task(compose(["task=view", f"path={out}", f"task.export={tmp_path / 'exp'}"]), tmp_path / "run")
    e = tmp_path / "exp"
    assert summary["characters"] == ["alice", "bob"] and sorted(p.name for p in (e / "audio").iterdir()) == [
        "listener_input.wav", "speaker_input.wav"]
    page = (e / "index.html").read_text()
    for f in ("viewer.js", "viewer.css", "three.bundle.min.js", "scene.js"):
        assert (e / f).is_file() and f"'{f}'" in page
    assert "http" not in page and "files/" not in (e / "scene.js").read_text()
    with pytest.raises(FormatError, match="x.bvh"):
        export(broken, tmp_path / "bad")
    assert not (tmp_path / "bad").exists() and not [p for p in tmp_path.iterdir() if p.name.startswith(".bad")]


def _raw_get(port: int, path: str) -> tuple[int, bytes]:
    """GET with the path sent as written (no client-side normalization of ``..``)."""
    s = socket.create_connection(("127.0.0.1", port), timeout=10)
    s.sendall(f"GET {path} HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n".encode())
    data = b""
    while chunk := s.recv(65536):
        data += chunk
    s.close()
    return int(data.split(b" ", 2)[1]), data


@pytest.fixture(scope="module")
def served(out):
    """uvicorn serving the fixture on a free loopback port, in a thread of this process."""
    from convsynth_jax.testing.web import serve_in_thread
    from convsynth_jax.viewer.server import create_viewer_app

    with serve_in_thread(create_viewer_app(out)) as (url, port):
        yield url, port


def test_traversal_probes_get_no_file(served):
    _, port = served
    for probe in ("/files/../../etc/passwd", "/files/%2e%2e/%2e%2e/etc/passwd", "/files/..%2f..%2f..%2fetc%2fpasswd",
                  "/../../etc/passwd", "/%2e%2e/%2e%2e/etc/passwd", "/files/%2e%2e%2freport.json", "/files/..\\report.json",
                  "/files/%2Fetc%2Fpasswd", "//etc/passwd", "/files//etc/passwd"):
        status, body = _raw_get(port, probe)
        assert status in (400, 404) and b"root:" not in body and b"characters" not in body, probe
    assert _raw_get(port, "/files/speaker_input.wav")[0] == 200


# ------------------------------------------------------------------------------------------ the browser
@pytest.fixture(scope="module")
def driver():
    from convsynth_jax.testing.web import find_browser, headless_chrome

    found = find_browser()
    if found is None:
        pytest.skip("no Chromium and chromedriver on this machine (apt-get install chromium chromium-driver)")
    pytest.importorskip("selenium.webdriver")
    d = headless_chrome(found, "--window-size=1000,800", "--mute-audio", "--autoplay-policy=no-user-gesture-required",
                        "--use-angle=swiftshader", "--enable-unsafe-swiftshader")
    d.set_page_load_timeout(30)
    yield d
    d.quit()


PIXELS_JS = """
var src = document.querySelector('#stage canvas'), w = src.width, h = src.height;
var c = document.createElement('canvas'); c.width = w; c.height = h;
var g = c.getContext('2d'); g.drawImage(src, 0, 0);
var d = g.getImageData(0, 0, w, h).data, k = w / src.clientWidth, V = window.convsynthViewer;
var boxes = [V.screen(0), V.screen(1)], counts = [[0, 0], [0, 0]], cw = Math.ceil(w / 10), sig = new Array(cw * Math.ceil(h / 10)).fill(0);
for (var y = 0; y < h; y++) { for (var x = 0; x < w; x++) {
  var i = 4 * (y * w + x), r = d[i], gg = d[i + 1], b = d[i + 2];
  var kind = (b > 110 && b > r + 50 && b > gg + 20) ? 0 : (r > 110 && gg < 0.6 * r && b < 0.5 * r) ? 1 : -1;
  if (kind < 0) { continue; }
  sig[Math.floor(y / 10) * cw + Math.floor(x / 10)]++;
  var box = boxes[kind], m = 0.15 * (box[3] - box[1]) + 6;
  var inside = x >= (box[0] - m) * k && x <= (box[2] + m) * k && y >= (box[1] - m) * k && y <= (box[3] + m) * k;
  counts[kind][inside ? 0 : 1]++;
}}
return {counts: counts, boxes: boxes, sig: sig, width: src.clientWidth, t: V.time(), error: document.getElementById('error').textContent};
"""


def _open(driver, url):
    from selenium.webdriver.support.ui import WebDriverWait

    driver.get(url)
    WebDriverWait(driver, 20).until(lambda d: d.execute_script("return document.body.dataset.state"))
    time.sleep(0.3)                                 # a few frames drawn
    return driver.execute_script(PIXELS_JS) if driver.execute_script("return document.body.dataset.state") == "ready" else None


def _both_drawn(px):
    (a_in, a_out), (b_in, b_out) = px["counts"]
    left, right = px["boxes"]
    assert a_in > 200 and b_in > 200, px["counts"]            # each character's colour inside its own box
    assert a_out < 0.05 * a_in and b_out < 0.05 * b_in, px["counts"]
    assert left[2] < right[0] + 0.2 * (right[2] - right[0])   # the first character on the left, facing the second


def test_browser_draws_both_characters_and_two_times_differ(driver, served):
    base, _ = served
    p1 = _open(driver, base + "/?t=1")
    assert p1 is not None and p1["t"] == pytest.approx(1.0) and not p1["error"]
    _both_drawn(p1)
    outside = driver.execute_script("return performance.getEntriesByType('resource').map(function (e) { return e.name; })")
    assert outside and all(u.startswith(base + "/") for u in outside), outside     # nothing from outside
    assert driver.execute_script("return document.getElementById('timeline').dataset.cursor") == "1.000"
    p8 = _open(driver, base + "/?t=8")
    assert p8["t"] == pytest.approx(8.0)
    _both_drawn(p8)
    moved = sum(abs(x - y) for x, y in zip(p1["sig"], p8["sig"]))   # character pixels per 10 x 10 cell
    assert moved > 0.08 * sum(p1["sig"]), (moved, sum(p1["sig"]))   # the waving arms (about a tenth of each body)


def test_browser_frames_the_characters_large_and_whole(driver, served):
    """The reset view fits the pair: together they span over half the stage's height (the camera
    used to stand so far back that seated characters filled about 40% of it) and stay inside it."""
    base, _ = served
    p = _open(driver, base + "/?t=1")
    w, h = driver.execute_script("var s = document.getElementById('stage'); return [s.clientWidth, s.clientHeight];")
    boxes = [driver.execute_script(f"return window.convsynthViewer.screen({k});") for k in (0, 1)]
    x0, y0 = min(b[0] for b in boxes), min(b[1] for b in boxes)
    x1, y1 = max(b[2] for b in boxes), max(b[3] for b in boxes)
    assert p is not None and y1 - y0 > 0.55 * h, (boxes, w, h)
    assert 0 <= x0 and x1 <= w and 0 <= y0 and y1 <= h, (boxes, w, h)


def test_browser_timeline_cursor_follows_the_audio_clock(driver, served):
    base, _ = served
    _open(driver, base + "/?t=2")
    read = ("var V = window.convsynthViewer, a = V.audio[0];"
            "return [a.currentTime, parseFloat(document.getElementById('timeline').dataset.cursor), V.clockSource(), a.paused,"
            " V.audio[1].currentTime];")
    driver.execute_script("window.convsynthViewer.play();")
    time.sleep(1.0)
    mid = driver.execute_script(read)
    time.sleep(0.6)
    late = driver.execute_script(read)
    driver.execute_script("window.convsynthViewer.pause();")
    time.sleep(0.4)                                   # frames drawn after the pause
    stop = driver.execute_script(read)
    assert mid[2] == "audio" and not mid[3] and mid[0] > 2.3, mid   # the audio plays and is the clock
    assert late[1] > mid[1] + 0.2 and abs(late[1] - late[0]) < 0.5, (mid, late)   # the cursor moves with it
    assert stop[3] and abs(stop[1] - stop[0]) < 0.03 and stop[0] > 2.5, stop   # paused: the cursor shows the audio's time
    assert abs(late[4] - late[0]) < 0.25, late         # the second file follows the first


def test_browser_shows_a_malformed_file_as_an_error(driver, broken):
    from convsynth_jax.testing.web import serve_in_thread
    from convsynth_jax.viewer.server import create_viewer_app

    with serve_in_thread(create_viewer_app(broken), log_level="critical") as (url, _):
        assert _open(driver, f"{url}/") is None
        state, text = driver.execute_script("return [document.body.dataset.state, document.getElementById('error').textContent]")
        assert state == "error" and "x.bvh" in text and "Cannot show" in text


def test_browser_draws_the_static_export_from_the_file_system(driver, out, tmp_path):
    from convsynth_jax.viewer.server import export

    export(out, tmp_path / "exp")
    px = _open(driver, (tmp_path / "exp" / "index.html").as_uri() + "?t=3")
    assert px is not None and px["t"] == pytest.approx(3.0) and not px["error"]
    _both_drawn(px)
    from selenium.webdriver.support.ui import WebDriverWait

    loaded = "return window.convsynthViewer.audio.map(function (a) { return a.error === null && a.readyState >= 1 && a.duration; })"
    WebDriverWait(driver, 10).until(lambda d: all(d.execute_script(loaded)))
    assert [round(x, 2) for x in driver.execute_script(loaded)] == [10.0, 10.0]     # the audio beside it, from file://
