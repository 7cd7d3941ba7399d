"""A screenshot of a study's trial page in headless Chromium (docs/study_trial.png).

    python experiments/study_screenshot.py --study DIR [--out docs/study_trial.png]

Serves the built study (``task=study_build``) on a loopback port with a throw-away database, agrees
to the consent page, begins, plays the first video to its end (the choice buttons become enabled)
and saves the page. Needs Chromium and chromedriver (Debian: chromium, chromium-driver)."""
import argparse
import shutil
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from convsynth_jax.testing.study import free_port, serve_subprocess  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--study", required=True)
    ap.add_argument("--out", default=str(REPO / "docs" / "study_trial.png"))
    ap.add_argument("--size", default="1000,760")
    args = ap.parse_args()
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import WebDriverWait

    browser = next((shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome") if shutil.which(n)), None)
    driver_exe = shutil.which("chromedriver")
    if not browser or not driver_exe:
        raise SystemExit("needs chromium and chromedriver")
    with tempfile.TemporaryDirectory() as tmp:
        port = free_port()
        proc = serve_subprocess(args.study, Path(tmp) / "answers.sqlite", port, "screenshot-admin-token-0123456789")
        opts = webdriver.ChromeOptions()
        opts.binary_location = browser
        for a in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--disable-gpu", f"--window-size={args.size}",
                  "--mute-audio", "--hide-scrollbars"):
            opts.add_argument(a)
        driver = webdriver.Chrome(service=Service(executable_path=driver_exe), options=opts)
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
