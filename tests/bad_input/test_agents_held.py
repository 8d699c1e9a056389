"""Agents that misbehave are held on every backend (issue 41, "nothing lost, nothing silent"):
an agent that catches the timeout interrupt is still recorded ``timeout``; one that eats memory
past ``--memory-limit-mb`` is recorded ``failed`` and its worker replaced (a leak cannot grow a
reused worker); the processes an agent starts end with its episode.

The agents live in a plugin module written into ``tmp_path``; they write what they did into a
marks folder (``CF_MARKS``), so that the tests count calls and pids instead of timing anything."""

from __future__ import annotations

import os
import re
from pathlib import Path

import pytest

from conceptfusion.errors import HarnessError
from harness.cli import main
from harness.runner.backends import run_jobs
from harness.runner.results import load_results
from harness.runner.run import RunConfig, episode_jobs, run_suites
from harness.runner.suites import get_suite

SUITE = "regression-rearrange"

AGENTS = '''
import os
import subprocess
import time
from pathlib import Path

import numpy as np

STOP = np.array([0, 0, 0, 0, 1], np.float32)
PUSH_NOTHING = np.array([0, 0, 0, 0, 0], np.float32)


def mark(name, text=None):
    with open(Path(os.environ["CF_MARKS"]) / name, "a") as fh:
        fh.write(f"{os.getpid() if text is None else text}\\n")


class Quiet:
    """Sees no scan and no ground truth (the random pusher's environment settings)."""

    privileged = False
    reads_scan = False

    def reset(self, seed=None):
        pass

    def act(self, observation, info=None):
        return STOP


class SwallowsTimeouts(Quiet):
    """Each act takes 3 s and catches every exception meanwhile (a bare except), the timeout
    interrupt included; six steps would take 18 s."""

    def act(self, observation, info=None):
        mark("acts")
        end = time.monotonic() + 3.0
        while True:
            try:
                if time.monotonic() >= end:
                    return PUSH_NOTHING
                time.sleep(0.05)
            except BaseException:
                pass


class Hoards(Quiet):
    """Keeps 300 MiB more of written memory at every step, and takes a second per step."""

    def reset(self, seed=None):
        self.hoard = []

    def act(self, observation, info=None):
        mark("hoard-acts")
        self.hoard.append(np.ones(300 << 20, np.uint8))
        time.sleep(1.0)
        return PUSH_NOTHING


LEAKED = []


class Leaks(Quiet):
    """Leaves 160 MiB behind in its process at every episode (a cache that only grows) and
    writes down its process id."""

    def reset(self, seed=None):
        LEAKED.append(np.ones(160 << 20, np.uint8))
        mark("leak-pids", os.getpid())


class LeavesChildren(Quiet):
    """Starts `sleep 1000` at every reset and, with CF_DOUBLE_FORK set, one more through a shell
    that exits at once (an orphan, as a daemon makes); writes their pids down."""

    def reset(self, seed=None):
        mark("children", subprocess.Popen(["sleep", "1000"]).pid)
        if os.environ.get("CF_DOUBLE_FORK"):
            subprocess.run(["sh", "-c", f"sleep 1000 & echo $! >> {Path(os.environ['CF_MARKS']) / 'children'}"], check=True)


class HangsWithAChild(Quiet):
    """Starts `sleep 1000`, writes its pid down, then sleeps through its episode."""

    def reset(self, seed=None):
        mark("children", subprocess.Popen(["sleep", "1000"]).pid)
        time.sleep(60)
'''


@pytest.fixture
def marks(tmp_path, monkeypatch) -> Path:
    """The agents' plugin module importable as ``cf_held`` and their marks folder."""
    (tmp_path / "cf_held.py").write_text(AGENTS)
    monkeypatch.syspath_prepend(str(tmp_path))
    folder = tmp_path / "marks"
    folder.mkdir()
    monkeypatch.setenv("CF_MARKS", str(folder))
    return folder


def _lines(path: Path) -> list[str]:
    return path.read_text().split() if path.exists() else []


def _job(agent: str, *, timeout_s: float = 600.0, episode: int = 0):
    config = RunConfig(suites=(SUITE,), agents=(agent,), limit=episode + 1)
    job = episode_jobs(get_suite(SUITE), config, "held")[episode]
    return type(job)(**{**job.__dict__, "timeout_s": timeout_s})


def _running(pid: int) -> bool:
    """Whether ``pid`` runs (a zombie has exited: nobody reaped it yet)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state not in ("Z", "X")


# -- timeouts an agent cannot swallow ---------------------------------------------------------

def test_an_agent_that_catches_the_timeout_is_stopped_at_its_next_return_on_the_serial_backend(marks):
    """The episode before warms the environment cache, so the swallowing agent's first act
    starts well inside its 1 s (``--timeout 1``); the interrupt comes during the act, which
    catches it, and the episode ends when that act returns: one act, not six, and ``timeout``."""
    warm = _job("cf_held:Quiet")
    slow = _job("cf_held:SwallowsTimeouts", timeout_s=1.0)
    first, rec = run_jobs([warm, slow], backend="serial")
    assert first["status"] == "ok", first["error"]
    assert rec["status"] == "timeout", rec
    assert re.fullmatch(r"episode exceeded 1 s; the job caught the SIGALRM interrupt (once|\d+ times); stopped on the "
                        r"serial backend when agent\.act returned, past its deadline", rec["error"]), rec["error"]
    assert len(_lines(marks / "acts")) == 1


def test_an_agent_that_catches_the_timeout_is_stopped_on_the_process_backend(marks):
    slow = _job("cf_held:SwallowsTimeouts", timeout_s=1.0)
    (rec,) = run_jobs([slow], backend="process", workers=1)
    assert rec["status"] == "timeout", rec
    assert rec["error"] == "episode exceeded 1 s; its worker was stopped"
    assert len(_lines(marks / "acts")) <= 1  # killed during its first act (or before it)


def test_an_error_raised_in_place_of_the_timeout_is_a_timeout(tmp_path, monkeypatch):
    """An agent that turns the interrupt into an error of its own is recorded ``timeout``, not
    ``failed``: past the deadline, whatever the episode raises ends it as a timeout."""
    (tmp_path / "cf_held_converter.py").write_text(
        "import time\n"
        "class Converts:\n"
        "    privileged, reads_scan = False, False\n"
        "    def reset(self, seed=None):\n"
        "        pass\n"
        "    def act(self, observation, info=None):\n"
        "        try:\n"
        "            time.sleep(30)\n"
        "        except BaseException as exc:\n"
        "            raise RuntimeError('planner gave up') from exc\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    rec, = run_jobs([_job("cf_held_converter:Converts", timeout_s=1.0)], backend="serial")
    assert rec["status"] == "timeout", rec
    assert rec["error"] == ("episode exceeded 1 s; the job caught the SIGALRM interrupt once; stopped on the serial "
                            "backend when the episode raised RuntimeError, past its deadline")


# -- a memory limit per episode (process backend) ---------------------------------------------

def test_an_episode_past_the_memory_limit_is_failed_and_its_worker_replaced(marks, tmp_path, capsys):
    """``cfharness run --memory-limit-mb 200``: the agent keeping 300 MiB more at each step is
    stopped in its first steps, and the next episode runs on a fresh worker."""
    main(["run", "--suite", SUITE, "--agent", "cf_held:Hoards", "--agent", "cf_held:Quiet", "--limit", "1", "--workers", "1",
          "--memory-limit-mb", "200", "--out", str(tmp_path / "run"), "--no-report"])
    capsys.readouterr()
    records = {r["agent"]: r for r in load_results(tmp_path / "run" / "results.jsonl")}
    rec = records["cf_held:Hoards"]
    assert rec["status"] == "failed", rec
    assert re.fullmatch(r"memory limit of 200 MiB exceeded: its worker held \d+ MiB more than when it started, during "
                        r"the episode; the worker was stopped", rec["error"]), rec["error"]
    assert len(_lines(marks / "hoard-acts")) <= 2  # stopped at once, not after six steps (1.8 GiB)
    assert records["cf_held:Quiet"]["status"] == "ok", records["cf_held:Quiet"]["error"]  # the run went on


def test_a_leaking_agent_does_not_grow_a_reused_worker(marks):
    """Each episode leaves 160 MiB behind; under a 300 MiB limit the worker holding it is
    replaced after every episode, so all three fit (a reused worker would hold 375 MiB and
    more from the second episode on)."""
    jobs = [_job("cf_held:Leaks", episode=i) for i in range(3)]
    records = list(run_jobs(jobs, backend="process", workers=1, memory_limit_mb=300))
    assert [r["status"] for r in records] == ["ok", "ok", "ok"], [r["error"] for r in records]
    assert len(set(_lines(marks / "leak-pids"))) == 3


@pytest.mark.parametrize("backend, why", [
    ("serial", "the serial backend runs episodes in this process, which it cannot stop without ending the run"),
    ("ray", "Ray tasks are held by Ray's own memory monitor"),
])
def test_the_memory_limit_is_refused_off_the_process_backend(backend, why):
    expected = (f"--memory-limit-mb: only for --backend process (each episode's worker process is watched and stopped "
                f"past the limit), got --backend {backend}: {why}")
    with pytest.raises(HarnessError) as caught:
        RunConfig(suites=(SUITE,), agents=("random-pusher",), backend=backend, memory_limit_mb=200)
    assert str(caught.value) == expected
    with pytest.raises(HarnessError) as caught:
        run_jobs([_job("random-pusher")], backend=backend, memory_limit_mb=200)
    assert str(caught.value) == expected


# -- an agent's processes end with its episode ------------------------------------------------

@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads process states from /proc")
@pytest.mark.parametrize("backend, double_fork", [("process", True), ("serial", False)])
def test_the_processes_an_agent_starts_end_with_its_episode(marks, tmp_path, monkeypatch, backend, double_fork):
    """On the process backend an orphaned grandchild (its shell exited) ends too; on the serial
    backend such an orphan is no longer below this process, so only the child is asked for."""
    if double_fork:
        monkeypatch.setenv("CF_DOUBLE_FORK", "1")
    config = RunConfig(suites=(SUITE,), agents=("cf_held:LeavesChildren",), limit=2, backend=backend, workers=1)
    try:
        records = run_suites(config, tmp_path / "run", progress=False)
        pids = [int(p) for p in _lines(marks / "children")]
        assert [r["status"] for r in records] == ["ok", "ok"], [r["error"] for r in records]
        assert len(pids) == (4 if double_fork else 2)
        assert [p for p in pids if _running(p)] == []
    finally:
        _kill(marks)


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads process states from /proc")
def test_the_processes_of_a_timed_out_episode_end_with_its_worker(marks):
    (rec,) = run_jobs([_job("cf_held:HangsWithAChild", timeout_s=1.0)], backend="process", workers=1)
    try:
        pids = [int(p) for p in _lines(marks / "children")]
        assert rec["status"] == "timeout", rec
        assert len(pids) == 1 and not _running(pids[0])
    finally:
        _kill(marks)


def _kill(marks: Path) -> None:
    """Clean up what a failing test left running."""
    for pid in _lines(marks / "children"):
        try:
            os.kill(int(pid), 9)
        except OSError:
            pass
