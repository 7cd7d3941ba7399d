"""Test helpers of the web applications (the study kit and the viewer): a free loopback port, an
app served by uvicorn in a thread of this process, and headless Chromium driven by Selenium
(skipped by the tests, refused by the scripts, where no Chromium and chromedriver are installed).

Test helper only: no library module imports it."""
from __future__ import annotations

import shutil
import socket
import threading
import time
from contextlib import contextmanager

BROWSERS = ("chromium", "chromium-browser", "google-chrome")


def free_port() -> int:
    """A TCP port free on 127.0.0.1 just now (the operating system's choice)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@contextmanager
def serve_in_thread(app, log_level: str = "warning", start_timeout: float = 20.0):
    """uvicorn serving the ASGI ``app`` on a free loopback port in a daemon thread; yields
    (base URL, port) once the server has started, and stops it on leaving. Raises RuntimeError when
    it has not started within ``start_timeout`` seconds."""
    import uvicorn

    port = free_port()
    server = uvicorn.Server(uvicorn.Config(app, host="127.0.0.1", port=port, log_level=log_level))
    th = threading.Thread(target=server.run, daemon=True)
    th.start()
    deadline = time.monotonic() + start_timeout
    while not server.started and time.monotonic() < deadline:
        time.sleep(0.05)
    try:
        if not server.started:
            raise RuntimeError(f"uvicorn did not start on port {port} within {start_timeout} s")
        yield f"http://127.0.0.1:{port}", port
    finally:
        server.should_exit = True
        th.join(10)


def find_browser() -> tuple[str, str] | None:
    """(browser, chromedriver) paths of the first Chromium of ``BROWSERS`` on PATH beside a
    chromedriver, or None."""
    for name in BROWSERS:
        b = shutil.which(name)
        if b:
            d = shutil.which("chromedriver")
            if d:
                return b, d
    return None


def headless_chrome(found: tuple[str, str], *flags: str):
    """A Selenium Chrome driver of ``found`` (:func:`find_browser`'s pair): headless, without the
    sandbox and /dev/shm (neither is there in a container), with ``flags`` added."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    opts = webdriver.ChromeOptions()
    opts.binary_location = found[0]
    for a in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", *flags):
        opts.add_argument(a)
    return webdriver.Chrome(service=Service(executable_path=found[1]), options=opts)
