"""Headless Chromium for the browser tests (the HTML report and the map viewer).

One browser serves the whole session. It is Debian's ``chromium`` driven by its
``chromium-driver`` through Selenium (``.ci/run`` installs both); WebGL runs on SwiftShader, the
software renderer. On a machine without them these tests are skipped, the command that installs
them as the reason, so the README's test command passes on a fresh machine as written; with
``CF_REQUIRE_BROWSER=1`` (``.ci/run`` sets it, after installing both) a missing browser fails them
instead, so CI can never pass with the browser tests skipped. They are marked ``browser``:
``python -m pytest -m "not browser"`` leaves them out.

Screenshots go to ``$CF_TEST_ARTIFACTS`` when set, else ``tests/artifacts/browser/`` (git-ignored).
"""

from __future__ import annotations

import os
import shutil
import time
from pathlib import Path

import pytest

ARTIFACTS = Path(os.environ.get("CF_TEST_ARTIFACTS") or Path(__file__).resolve().parents[1] / "artifacts" / "browser")
_INSTALL = "apt-get install -y chromium chromium-driver (as .ci/run does) and pip install -e '.[dev]' (selenium)"


def _find(names, env):
    """The executable named by ``$env`` (when set and present) or the first of ``names`` on PATH."""
    if os.environ.get(env):
        return os.environ[env] if shutil.which(os.environ[env]) else None
    return next((p for p in map(shutil.which, names) if p), None)


REQUIRE_ENV = "CF_REQUIRE_BROWSER"
"""Set to ``1`` to fail, not skip, the browser tests when Chromium, its driver or Selenium is missing."""


def _missing(reason: str) -> None:
    """Skip (or, under ``CF_REQUIRE_BROWSER=1``, fail) the browser tests for ``reason``."""
    if os.environ.get(REQUIRE_ENV) == "1":
        pytest.fail(f"{reason} ({REQUIRE_ENV}=1: the browser tests must run here)", pytrace=False)
    pytest.skip(reason)


@pytest.fixture(scope="session")
def chromium():
    """A headless Chromium (Selenium WebDriver), 1280x800, shared by the session."""
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
    except ImportError:
        _missing(f"the browser tests need selenium: {_INSTALL}")
    binary = _find(("chromium", "chromium-browser", "google-chrome"), "CF_CHROMIUM")
    driver_path = _find(("chromedriver", "chromium-driver"), "CF_CHROMEDRIVER")
    if not binary or not driver_path:
        missing = " and ".join(n for n, p in (("chromium", binary), ("chromedriver", driver_path)) if not p)
        _missing(f"headless Chromium not found ({missing} not on PATH): {_INSTALL}")
    opts = webdriver.ChromeOptions()
    opts.binary_location = binary
    for arg in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--window-size=1280,800",
                "--enable-unsafe-swiftshader", "--use-angle=swiftshader", "--ignore-gpu-blocklist",
                "--disable-extensions", "--no-first-run", "--allow-file-access-from-files"):
        opts.add_argument(arg)
    opts.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service(driver_path), options=opts)  # an explicit driver: no download
    driver.set_page_load_timeout(60)
    driver.set_script_timeout(60)
    yield driver
    driver.quit()


@pytest.fixture(scope="session")
def artifacts() -> Path:
    """Folder for screenshots."""
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    return ARTIFACTS


def _wait_for(driver, script: str, *, timeout: float = 30.0, what: str = "the page"):
    """Poll ``return <script>`` until it gives a truthy value; returns it (fails with ``what``)."""
    deadline = time.monotonic() + timeout
    while True:
        value = driver.execute_script("return " + script)
        if value:
            return value
        if time.monotonic() > deadline:
            logs = [e["message"] for e in driver.get_log("browser")][-10:]
            pytest.fail(f"{what}: {script!r} still false after {timeout} s; browser log: {logs}")
        time.sleep(0.05)


@pytest.fixture(scope="session")
def wait_for():
    """``wait_for(driver, script, timeout=..., what=...)``: poll ``return <script>`` until truthy."""
    return _wait_for
