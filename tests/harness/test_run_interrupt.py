"""Ctrl-C (and SIGTERM) stop ``cfharness run`` cleanly, and ``--resume`` finishes the run (issue 41):
no traceback, the finished records kept, one line with the resume command, exit status 130
(143 for SIGTERM); a resume refuses a results file that holds another run's records."""

from __future__ import annotations

import json
import os
import shlex
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from harness.cli import main
from harness.runner.results import load_results

REPO = Path(__file__).resolve().parents[2]

SLOW = '''
import os
import time

import numpy as np


class SlowStop:
    """Stops at once in the first episode of its process; in later ones it first sleeps
    CF_SLOW_S seconds (default 0): a slow, cheap tabletop agent."""

    privileged = False
    reads_scan = False
    episodes = 0

    def reset(self, seed=None):
        SlowStop.episodes += 1

    def act(self, observation, info=None):
        if SlowStop.episodes > 1:
            time.sleep(float(os.environ.get("CF_SLOW_S", "0")))
        return np.array([0, 0, 0, 0, 1], np.float32)
'''

ARGS = ["run", "--suite", "rearrange", "--agent", "cf_slow_stop:SlowStop", "--limit", "3", "--backend", "serial", "--no-report"]


@pytest.mark.parametrize("signum, status, name", [(signal.SIGINT, 130, "Ctrl-C"), (signal.SIGTERM, 143, "SIGTERM")])
def test_a_stopped_run_keeps_its_records_says_how_to_resume_and_resumes(tmp_path, monkeypatch, capsys, signum, status, name):
    (tmp_path / "cf_slow_stop.py").write_text(SLOW)
    out = tmp_path / "run"
    env = {**os.environ, "MUJOCO_GL": "egl", "CF_SLOW_S": "120", "PYTHONPATH": os.pathsep.join([str(tmp_path), str(REPO)])}
    proc = subprocess.Popen([sys.executable, "-m", "harness.cli", *ARGS, "--out", str(out)], cwd=REPO, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    results = out / "results.jsonl"
    try:
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline and proc.poll() is None and not (results.exists() and results.read_text()):
            time.sleep(0.1)
        assert proc.poll() is None and results.read_text().count("\n") == 1, "the first episode did not finish"
        proc.send_signal(signum)  # during the second episode's sleep
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == status, err
    assert "Traceback" not in err, err
    last = err.strip().splitlines()[-1]
    resume = f"cfharness run --out {shlex.quote(str(out))} --resume"
    assert last == (f"cfharness run: stopped by {name}; 1 finished record kept in {results} (3 planned); "
                    f"finish the run with: {resume}"), err
    assert len(load_results(results)) == 1

    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delenv("CF_SLOW_S", raising=False)
    assert main(shlex.split(resume)[1:] + ["--no-report"]) == 0  # the command as printed, here
    records = load_results(results)
    assert sorted(r["episode_id"] for r in records) == ["tabletop-v1-0000", "tabletop-v1-0001", "tabletop-v1-0002"]
    assert all(r["status"] == "ok" for r in records), [r["error"] for r in records]
    assert len({r["run_id"] for r in records}) == 1


def test_resume_refuses_another_runs_records_naming_file_and_line(tmp_path, capsys):
    out = tmp_path / "run"
    args = ["run", "--suite", "rearrange", "--agent", "random-pusher", "--limit", "1", "--backend", "serial", "--no-report"]
    assert main([*args, "--out", str(tmp_path / "other")]) == 0
    assert main([*args, "--out", str(out)]) == 0
    results = out / "results.jsonl"
    foreign = json.loads((tmp_path / "other" / "results.jsonl").read_text().splitlines()[0])
    with open(results, "a") as fh:  # what two runs writing to one folder used to leave
        fh.write(json.dumps({**foreign, "episode_id": "tabletop-v1-0001"}) + "\n")
    capsys.readouterr()
    rc = main(["run", "--out", str(out), "--resume", "--no-report"])
    err = capsys.readouterr().err
    run_id = json.loads((out / "run.json").read_text())["config"]["run_id"]
    assert rc == 2
    assert err == (f"cfharness run: {results}: line 2: expected records of this folder's run {run_id!r} (its run.json), got a "
                   f"record of run {foreign['run_id']!r}; records of another run do not belong here: move them to their "
                   "own folder and resume again\n")
    assert len(load_results(results)) == 2  # nothing appended after them
