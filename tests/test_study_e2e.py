"""The study kit end to end: ``task=study_build`` on the tiny corpus (15 s windows, 2 segments x 2
pairs + 1 attention check, 96 x 108 panels at 8 fps; played 8 times faster), its videos checked (H.264 + AAC, hashes), served by a
real uvicorn process, answered by a real headless Chromium driven by selenium (one participant
completes the study, a second stops half-way and resumes with the token), then
``task=study_analyze`` on the export must report exactly the counts those clicks produced.

The browser test skips when no Chromium and chromedriver are found (``.ci/run`` installs Debian's
``chromium`` and ``chromium-driver`` where it can, beside the tests: the test waits for that install).
``CONVSYNTH_STUDY_SCREENSHOT=FILE.png`` saves a trial page (docs/study.md's picture)."""
from __future__ import annotations

import csv
import io
import json
import os
import time
from pathlib import Path

import pandas as pd
import pytest

pytest.importorskip("fastapi")

ADMIN = "e2e-admin-token-0123456789abcdef"


@pytest.fixture(scope="module")
def tiny_study(tiny_corpus_dir, main_run, tmp_path_factory):
    """Built with the main job's cache (its fitted graphs and compiled search kernels for the same
    15 s windows), so only synthesis and rendering are new work."""
    from convsynth_jax.config import compose, run_task

    cache = (main_run[0] / "cache_dir.txt").read_text().strip()
    out = tmp_path_factory.mktemp("study_build")
    summary = run_task(compose([
        "task=study_build", "corpus=synthetic_tiny", f"corpus.root={tiny_corpus_dir}", f"cache_dir={cache}",
        "progress=false", "task.segments=1",   # the paper's four pairs; the paper preset solves few tiny-corpus windows
        "task.attention_stimuli=1", "task.attention_per_participant=1", "task.trials_per_participant=4",
        "task.panel_width=96", "task.panel_height=108", "task.render_fps=8", f"task.out={out / 'study'}"]), out / "run")
    return out / "study", summary


def test_study_build_writes_balanced_stimuli_with_h264_aac_videos_and_hashes(tiny_study):
    from convsynth_jax.render import probe_streams
    from convsynth_jax.study.build import load_study_manifest, sha256_of

    study, summary = tiny_study
    m = load_study_manifest(study)
    st = m["stimuli"]
    assert summary["num_stimuli"] == 5 == len(st) and summary["num_attention"] == 1
    pairs = [s for s in st if s["kind"] == "pair"]
    assert [s["pair"] for s in pairs] == ["gt_vs_all", "all_vs_no_lr", "all_vs_no_hp", "all_vs_none"]
    assert sum(s["left"] == s["condition_a"] for s in pairs) == 2            # sides balanced over the pairs
    assert len({(s["session"], s["window"]) for s in st}) == 1
    for s in st:
        f = study / s["file"]
        assert sha256_of(f) == s["sha256"]
        probe = probe_streams(f)
        assert probe["video"] == 1 and probe["audio"] == 1 and abs(probe["duration"] - 15.0) < 0.2
    assert all(len(s["seeds"]) == 8 for s in pairs)                            # 4 conditions x 2 characters
    table = pd.read_csv(study / "manifest.csv")
    assert list(table["id"]) == [s["id"] for s in st] and (table["sha256"] == [s["sha256"] for s in st]).all()


def _browser():
    """(browser, chromedriver) paths, or None. While ``.ci/run`` installs them in the background it names a
    file in ``CONVSYNTH_BROWSER_INSTALL`` that appears when apt-get is done: wait for it (at most 15 min)."""
    from convsynth_jax.testing.web import find_browser

    marker = os.environ.get("CONVSYNTH_BROWSER_INSTALL")
    deadline = time.monotonic() + 900
    while marker and not os.path.exists(marker) and time.monotonic() < deadline:
        time.sleep(1.0)
    return find_browser()


def test_headless_chromium_participants_and_analysis_match_the_clicks(tiny_study, tmp_path):
    found = _browser()
    if found is None:
        pytest.skip("no Chromium and chromedriver on this machine (apt-get install chromium chromium-driver)")
    pytest.importorskip("selenium.webdriver")
    from selenium.common.exceptions import StaleElementReferenceException
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import WebDriverWait

    from convsynth_jax.config import compose, run_task
    from convsynth_jax.study.build import load_study_manifest
    from convsynth_jax.testing.study import serve_subprocess
    from convsynth_jax.testing.web import free_port, headless_chrome

    study, _ = tiny_study
    stim = {s["id"]: s for s in load_study_manifest(study)["stimuli"]}
    port = free_port()
    proc = serve_subprocess(study, tmp_path / "answers.sqlite", port, ADMIN)
    base = f"http://127.0.0.1:{port}"
    driver = headless_chrome(found, "--disable-gpu", "--window-size=900,700", "--mute-audio")
    driver.set_page_load_timeout(60)
    wait = WebDriverWait(driver, 60, ignored_exceptions=(StaleElementReferenceException,))
    clicks = []                                     # (participant token, stimulus id, side)

    def answer_trials(token: str, k: int, how_many: int | None):
        done = 0
        while how_many is None or done < how_many:
            if "/done" in driver.current_url:
                return
            wait.until(lambda d: d.find_elements(By.ID, "play") or "/done" in d.current_url)
            if "/done" in driver.current_url:
                return
            left = driver.find_element(By.ID, "choose-left")
            assert not left.is_enabled()           # the choice waits for the video to end
            src = driver.find_element(By.ID, "stimulus").get_attribute("src")
            sid = Path(src).stem
            progress = driver.find_element(By.ID, "progress").text
            driver.execute_script("document.getElementById('stimulus').playbackRate = 8;")   # 15 s videos in 2 s
            driver.find_element(By.ID, "play").click()
            wait.until(lambda d: d.find_element(By.ID, "choose-left").is_enabled())
            played = driver.execute_script("var v = document.getElementById('stimulus');"
                                           "return [v.ended, v.duration, v.currentTime, v.error === null, v.videoWidth];")
            assert played[0] and played[3] and played[1] > 14.5 and played[4] > 0   # it played to the end
            if os.environ.get("CONVSYNTH_STUDY_SCREENSHOT") and not clicks:
                driver.save_screenshot(os.environ["CONVSYNTH_STUDY_SCREENSHOT"])
            s = stim[sid]
            side = s["expected"] if s["kind"] == "attention" else ("left" if (len(clicks) + k) % 3 else "right")
            driver.find_element(By.ID, f"choose-{side}").click()
            clicks.append((token, sid, side))
            wait.until(lambda d: "/done" in d.current_url or d.find_elements(By.ID, "progress")
                       and d.find_element(By.ID, "progress").text != progress)
            done += 1

    try:
        codes = []
        for k in range(2):
            driver.delete_all_cookies()
            driver.get(base + "/")
            driver.find_element(By.ID, "consent").click()
            wait.until(lambda d: d.find_elements(By.ID, "token"))
            token = driver.find_element(By.ID, "token").text
            driver.find_element(By.ID, "begin").click()
            if k == 1:                               # stops half-way, comes back later with the token
                answer_trials(token, k, 2)
                driver.get(base + "/")
                driver.find_element(By.ID, "resume-token").send_keys(token)
                driver.find_element(By.ID, "resume").click()
                wait.until(lambda d: d.find_elements(By.ID, "progress"))
                assert driver.find_element(By.ID, "progress").text == "Video 3 of 5"
            answer_trials(token, k, None)
            wait.until(lambda d: d.find_elements(By.ID, "code"))
            codes.append(driver.find_element(By.ID, "code").text)
        import httpx

        export = httpx.get(base + "/admin/export.csv", headers={"Authorization": f"Bearer {ADMIN}"}).text
    finally:
        driver.quit()
        proc.kill()
        proc.wait()
    assert len(clicks) == 10 and len(set(codes)) == 2 and all(len(c) == 8 for c in codes)
    rows = list(csv.DictReader(io.StringIO(export)))
    assert sorted((r["participant"], r["stimulus"], r["chosen_side"]) for r in rows) == sorted(clicks)
    (tmp_path / "export.csv").write_text(export)
    summary = run_task(compose(["task=study_analyze", f"task.answers={tmp_path / 'export.csv'}", f"task.study={study}"]),
                       tmp_path / "analysis")
    expected = {}
    for _, sid, side in clicks:
        s = stim[sid]
        if s["kind"] == "pair":
            e = expected.setdefault(s["pair"], [0, 0])
            e[0] += s[side] == s["condition_a"]
            e[1] += 1
    got = {r["pair"]: [r["preferred_a"], r["total"]] for r in summary["rows"]}
    assert got == expected and summary["excluded"] == 0 and summary["participants"] == 2
    assert (tmp_path / "analysis" / "figure6.png").is_file()
    assert json.loads((tmp_path / "analysis" / "summary.json").read_text())["answers"] == 10
