"""A screenshot of a study's trial page in headless Chromium (docs/study_trial.png).

    python experiments/study_screenshot.py --study DIR [--out docs/study_trial.png]

Serves the built study (``task=study_build``) on a loopback port with a throw-away database, agrees
to the consent page, begins, plays the first video to its end (the choice buttons become enabled)
and saves the page. Needs Chromium and chromedriver (Debian: chromium, chromium-driver)."""
import argparse
import tempfile
from pathlib import Path

from convsynth_jax.testing.study import serve_subprocess
from convsynth_jax.testing.web import find_browser, free_port, headless_chrome
from convsynth_jax.api import REPO


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--study", required=True)
    ap.add_argument("--out", default=str(REPO / "docs" / "study_trial.png"))
    ap.add_argument("--size", default="1000,760")
    args = ap.parse_args()
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import WebDriverWait

    found = find_browser()
    if found is None:
        raise SystemExit("needs chromium and chromedriver")
    with tempfile.TemporaryDirectory() as tmp:
        port = free_port()
        proc = serve_subprocess(args.study, Path(tmp) / "answers.sqlite", port, "screenshot-admin-token-0123456789")
        driver = headless_chrome(found, "--disable-gpu", f"--window-size={args.size}", "--mute-audio", "--hide-scrollbars")
        try:
            wait = WebDriverWait(driver, 120)
            driver.get(f"http://127.0.0.1:{port}/")
            driver.find_element(By.ID, "consent").click()
            wait.until(lambda d: d.find_elements(By.ID, "begin"))
            driver.find_element(By.ID, "begin").click()
            wait.until(lambda d: d.find_elements(By.ID, "play"))
            driver.find_element(By.ID, "play").click()
            wait.until(lambda d: d.find_element(By.ID, "choose-left").is_enabled())
            driver.execute_script("var v = document.getElementById('stimulus'); v.currentTime = v.duration / 2;")
            wait.until(lambda d: d.execute_script("return document.getElementById('stimulus').readyState >= 2"))
            driver.save_screenshot(args.out)
        finally:
            driver.quit()
            proc.kill()
            proc.wait()
    print(args.out)


if __name__ == "__main__":
    main()
