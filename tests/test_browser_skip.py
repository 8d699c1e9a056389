"""The browser tests skip on a machine without Chromium (the README's test command passes there as
written) and fail instead under ``CF_REQUIRE_BROWSER=1``, which ``.ci/run`` sets."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def _run_one_browser_test(**env) -> subprocess.CompletedProcess:
    env = {**os.environ, "CF_CHROMIUM": "/nonexistent/chromium", **env}  # no browser to be found
    env = {k: v for k, v in env.items() if v is not None}  # None: unset
    return subprocess.run([sys.executable, "-m", "pytest", "-q", "-n", "0", "-p", "no:cacheprovider", "-rs",
                           "tests/browser/test_report_page.py"], cwd=REPO, env=env, capture_output=True, text=True, timeout=600)


def test_without_chromium_the_browser_tests_skip_naming_the_install_line():
    done = _run_one_browser_test(CF_REQUIRE_BROWSER=None)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "skipped" in done.stdout and "passed" not in done.stdout and "failed" not in done.stdout
    assert "headless Chromium not found (chromium not on PATH): apt-get install -y chromium chromium-driver" in done.stdout


def test_under_ci_a_missing_chromium_fails_them():
    done = _run_one_browser_test(CF_REQUIRE_BROWSER="1")
    assert done.returncode == 1, done.stdout + done.stderr
    assert "CF_REQUIRE_BROWSER=1: the browser tests must run here" in done.stdout and "skipped" not in done.stdout
