"""``pip install .`` (a wheel, not an editable install) carries every data file the suites need:
the wheel is built, installed into a fresh virtual environment, and a one-episode suite runs from
a folder outside the repository with the installed package alone."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import venv
import zipfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.install


def test_the_wheel_holds_the_data_and_runs_a_suite_installed(tmp_path):
    wheels = tmp_path / "wheels"
    # no build isolation: setuptools is already here, and the machine may be offline but for PyPI
    subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "--no-build-isolation", "-w", str(wheels), str(REPO)],
                   check=True, capture_output=True, text=True, timeout=900)
    (wheel,) = wheels.glob("conceptfusion_harness-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    # every committed data file the suites, floors and viewer read is in it
    tracked = subprocess.run(["git", "ls-files", "scenes", "harness/data", "harness/viewer/static", "conceptfusion/perception"],
                             cwd=REPO, check=True, capture_output=True, text=True).stdout.split()
    data = [p for p in tracked if not p.endswith(".py")]
    assert data and not [p for p in data if p not in names], [p for p in data if p not in names][:5]

    # a fresh environment: the dependencies come from this one (offline), the project from the wheel only
    env_dir = tmp_path / "env"
    venv.EnvBuilder(system_site_packages=True, with_pip=False).create(env_dir)
    python = env_dir / "bin" / "python"
    subprocess.run([sys.executable, "-m", "pip", "--python", str(python), "install", "-q", "--no-deps", str(wheel)],
                   check=True, capture_output=True, text=True, timeout=600)
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"} | {"MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    where = subprocess.run([str(python), "-c", "import harness, scenes; print(harness.__file__); print(scenes.__file__)"],
                           cwd=outside, env=env, check=True, capture_output=True, text=True).stdout.split()
    assert all(Path(p).is_relative_to(env_dir) for p in where), where  # the installed copy, not the checkout
    done = subprocess.run([str(python), "-m", "harness.cli", "run", "--suite", "rearrange-v2", "--agent", "random-pusher",
                           "--limit", "1", "--backend", "serial", "--out", str(outside / "run"), "--no-report"],
                          cwd=outside, env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stdout + done.stderr
    (record,) = [json.loads(line) for line in (outside / "run" / "results.jsonl").read_text().splitlines()]
    assert record["status"] == "ok" and record["suite"] == "rearrange-v2" and record["episode_id"].startswith("rearrange-v2-sealed-")
