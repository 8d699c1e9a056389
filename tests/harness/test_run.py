"""Runs end to end: regression bounds, every agent through a full episode, backends that agree,
and a run killed with SIGKILL that resumes to the same summary."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from harness.runner.backends import run_jobs
from harness.commands import _check_bounds
from harness.runner.results import load_results
from harness.runner.run import RunConfig, episode_jobs, run_suites
from harness.report.stats import summarize
from harness.runner.suites import get_suite

REPO = Path(__file__).resolve().parents[2]


def _outcome(rec: dict) -> tuple:
    """What must not depend on where or when an episode ran (not its timings)."""
    return rec["suite"], rec["agent"], rec["episode_id"], rec["status"], json.dumps(rec["metrics"], sort_keys=True)


@pytest.mark.gate
def test_regression_suites_meet_their_bounds(tmp_path):
    """The CI regression gate: every built-in agent of both tasks (map-equipped, map-free,
    random and privileged) runs its pinned episodes headless, with oracle perception and with
    the embedded one, each is scored, and none falls below its calibrated lower bound or rises above
    its upper bound (:mod:`harness.runner.bounds`)."""
    suites = ("regression-rearrange", "regression-rearrange-embedded", "regression-search")
    # No recordings: the gate checks bounds (recordings have their own tests, test_replay.py).
    records = run_suites(RunConfig(suites=suites, backend="process", workers=2, record="none"), tmp_path, progress=False)
    expected = sum(sum(get_suite(s).agent_limits.values()) for s in suites)
    assert len(records) == expected
    assert all(r["status"] == "ok" for r in records), [r["error"] for r in records if r["status"] != "ok"]
    for r in records:
        assert isinstance(r["metrics"]["success"], bool) and r["metrics"]["steps"] >= 1
        if r["task"] == "object_search":
            assert 0.0 <= r["metrics"]["spl"] <= 1.0 and r["metrics"]["distance_to_goal"] >= 0.0
    assert _check_bounds(records, suites) == 0
    by_agent = {}
    for r in records:
        by_agent.setdefault(r["agent"], []).append(r["metrics"]["success"])
    by_agent = {a: sum(v) / len(v) for a, v in by_agent.items()}
    assert by_agent["map-pusher"] > by_agent["random-pusher"]
    assert by_agent["map-navigator"] > by_agent["random-walker"]


def test_bounds_catch_an_agent_below_them():
    suite = get_suite("regression-rearrange")
    recs = [{"suite": suite.name, "agent": "map-pusher", "episode_id": f"e{i}", "seed": 0, "status": "ok",
             "metrics": {"success": False}} for i in range(suite.agent_limits["map-pusher"])]
    assert _check_bounds(recs, (suite.name,), agents=("map-pusher",)) == 1


@pytest.mark.parametrize("suite, agent", [("regression-rearrange", "map-pusher"), ("regression-search", "map-navigator")])
def test_map_agents_complete_an_episode_with_embedded_perception(tmp_path, suite, agent):
    config = RunConfig(suites=(suite,), agents=(agent,), limit=1, backend="serial")
    jobs = episode_jobs(get_suite(suite), config, "t")
    jobs = [type(j)(**{**j.__dict__, "agent_kwargs": {**j.agent_kwargs, "encoder": "embedded"}}) for j in jobs]
    (rec,) = list(run_jobs(jobs, backend="serial"))
    assert rec["status"] == "ok", rec["error"]
    assert rec["encoder"] == "embedded" and rec["extras"]["uses_map"] is True and rec["extras"]["privileged"] is False
    assert isinstance(rec["metrics"]["success"], bool) and rec["metrics"]["steps"] >= 1


def _records(suite: str, agent: str, outcomes: list[bool], status: str = "ok") -> list[dict]:
    return [{"suite": suite, "agent": agent, "encoder": "oracle", "episode_id": f"e{i}", "seed": 0, "status": status,
             "metrics": {"success": ok}}
            for i, ok in enumerate(outcomes)]


def test_fail_fast_stops_exactly_when_a_lower_bound_is_out_of_reach(capsys):
    from harness.commands import fail_fast_stop

    suite = get_suite("regression-rearrange")
    n, lower = suite.agent_limits["map-pusher"], suite.lower_bounds["map-pusher"]
    jobs = episode_jobs(suite, RunConfig(suites=(suite.name,), agents=("map-pusher",)), "t")
    assert len(jobs) == n
    stop = fail_fast_stop(jobs, (suite.name,), agents=("map-pusher",))
    allowed = n - int(np.ceil(lower * n - 1e-9))  # failures the lower bound tolerates
    verdicts = [stop(r) for r in _records(suite.name, "map-pusher", [False] * (allowed + 1))]
    assert verdicts == [False] * allowed + [True]
    # the verdict on the records that ran: broken for certain, reported as stopped early
    partial = _records(suite.name, "map-pusher", [False] * (allowed + 1))
    assert _check_bounds(partial, (suite.name,), agents=("map-pusher",), stopped_early=True) == 1
    err = capsys.readouterr().err
    assert "before --fail-fast stopped the run" in err and "below its lower bound" in err and "note:" in err
    # one failure fewer is not settled: no regression, only a note that the run stopped
    assert _check_bounds(partial[:-1], (suite.name,), agents=("map-pusher",), stopped_early=True) == 0
    # a resumed run counts the records it already holds: one more failure settles it
    resumed = fail_fast_stop(jobs, (suite.name,), agents=("map-pusher",), done=partial[:-1])
    assert resumed(_records(suite.name, "map-pusher", [False] * (allowed + 1))[-1])
    # a crash settles at once; agents without a bound never stop the run
    assert fail_fast_stop(jobs, (suite.name,), agents=("map-pusher",))(_records(suite.name, "map-pusher", [False], "failed")[0])
    assert not fail_fast_stop(jobs, (suite.name,), agents=("map-pusher",))(_records(suite.name, "random-pusher", [True])[0])


def test_fail_fast_stops_an_upper_bound_once_passed():
    from harness.commands import fail_fast_stop

    suite = get_suite("regression-search")
    n, upper = suite.agent_limits["random-walker"], suite.upper_bounds["random-walker"]
    jobs = episode_jobs(suite, RunConfig(suites=(suite.name,), agents=("random-walker",)), "t")
    stop = fail_fast_stop(jobs, (suite.name,), agents=("random-walker",))
    allowed = int(np.floor(upper * n + 1e-9))
    assert [stop(r) for r in _records(suite.name, "random-walker", [True] * (allowed + 1))] == [False] * allowed + [True]


def test_execute_stops_when_told_and_resume_finishes_the_run(tmp_path):
    from harness.runner.run import plan_run

    config = RunConfig(suites=("regression-rearrange",), agents=("random-pusher",), limit=3, backend="serial")
    plan = plan_run(config, tmp_path)
    records = plan.execute(stop=lambda rec: True, progress=False)
    assert len(records) == 1
    rest = plan_run(config, tmp_path, resume=True)
    assert len(rest.todo) == 2 and len(rest.execute(progress=False)) == 3


def _cheap_jobs(limit: int = 2):
    config = RunConfig(suites=("regression-rearrange",), agents=("random-pusher", "oracle-pusher"), limit=limit)
    return episode_jobs(get_suite("regression-rearrange"), config, "same")


def test_process_pool_and_ray_give_the_serial_results():
    jobs = _cheap_jobs()
    serial = sorted(_outcome(r) for r in run_jobs(jobs, backend="serial"))
    pool = sorted(_outcome(r) for r in run_jobs(jobs, backend="process", workers=2))
    assert pool == serial
    pytest.importorskip("ray", reason="the ray extra is part of dev; this runs wherever it is installed")
    import ray

    try:
        got = sorted(_outcome(r) for r in run_jobs(jobs, backend="ray", workers=2))
    finally:
        ray.shutdown()
    assert got == serial
    assert any(o[3] == "ok" and '"success": true' in o[4] for o in serial)  # the oracle solves some


SLOW = '''
import time


class SleepsInReset:
    """Takes a minute to reset: past any short timeout."""

    privileged = False

    def reset(self, seed=None):
        time.sleep(60)

    def act(self, observation, info=None):
        return None
'''


def test_a_timed_out_episode_is_recorded_and_the_run_goes_on(tmp_path, monkeypatch):
    (tmp_path / "cf_slow_agent.py").write_text(SLOW)
    monkeypatch.syspath_prepend(str(tmp_path))
    jobs = _cheap_jobs(1)
    slow = type(jobs[0])(**{**jobs[0].__dict__, "agent": "cf_slow_agent:SleepsInReset", "agent_kwargs": {}, "timeout_s": 1.0})
    recs = {r["agent"]: r for r in run_jobs([slow, jobs[-1]], backend="process", workers=2)}
    assert recs[slow.agent]["status"] == "timeout" and "exceeded" in recs[slow.agent]["error"]
    assert recs[jobs[-1].agent]["status"] == "ok"


REPORTER = '''
import os
import sys


class ReportsItsWorker:
    """Fails at reset with what its worker process holds: an environment mark and whether the
    text tower's library was imported before the job ran."""

    privileged = False

    def reset(self, seed=None):
        raise RuntimeError(f"mark={os.environ.get('CF_WORKER_MARK')} preloaded={'sentence_transformers' in sys.modules}")

    def act(self, observation, info=None):
        return None
'''


def test_pool_workers_start_warm_with_the_parents_environment(tmp_path, monkeypatch):
    """Workers fork from a fork server that imported the heavy modules once (the job did not
    import the text tower's library, yet it is there) and take the environment variables the
    parent has when each worker starts, also after the server started."""
    (tmp_path / "cf_worker_reporter.py").write_text(REPORTER)
    monkeypatch.syspath_prepend(str(tmp_path))
    job = _cheap_jobs(1)[0]
    job = type(job)(**{**job.__dict__, "agent": "cf_worker_reporter:ReportsItsWorker", "agent_kwargs": {}})
    for mark in ("first", "second"):
        monkeypatch.setenv("CF_WORKER_MARK", mark)
        (rec,) = run_jobs([job], backend="process", workers=1)
        assert rec["status"] == "failed" and f"mark={mark} preloaded=True" in rec["error"], rec["error"]


def _cli(*args, **kw):
    return subprocess.Popen([sys.executable, "-m", "harness.cli", *args], cwd=REPO, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, env={**os.environ, "MUJOCO_GL": "egl"}, **kw)


def test_sigkill_then_resume_gives_the_uninterrupted_summary(tmp_path):
    args = ["run", "--suite", "regression-rearrange", "--agent", "random-pusher", "--agent", "oracle-pusher",
            "--limit", "3", "--backend", "serial", "--no-report"]
    whole = _cli(*args, "--out", str(tmp_path / "whole"))
    out, _ = whole.communicate(timeout=600)
    assert whole.returncode == 0, out

    killed = _cli(*args, "--out", str(tmp_path / "killed"))
    results = tmp_path / "killed" / "results.jsonl"
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline:
        if results.exists() and results.read_text().count("\n") >= 2:
            break
        time.sleep(0.05)
    os.kill(killed.pid, signal.SIGKILL)
    killed.wait()
    n_before = len(load_results(results))
    assert 2 <= n_before < 6
    with open(results, "a") as fh:  # what a kill in the middle of a write leaves behind
        fh.write('{"suite": "regression-rearr')
    resumed = _cli(*args, "--out", str(tmp_path / "killed"), "--resume")
    out, _ = resumed.communicate(timeout=600)
    assert resumed.returncode == 0, out

    def summary(d):
        rows = [r.as_dict() for r in summarize(load_results(d / "results.jsonl"))]
        for row in rows:
            row.pop("wall_s", None)
        return rows

    a, b = load_results(tmp_path / "whole" / "results.jsonl"), load_results(results)
    assert len(a) == len(b) == 6
    assert sorted(map(_outcome, a)) == sorted(map(_outcome, b))
    assert summary(tmp_path / "whole") == summary(tmp_path / "killed")


def test_resume_refuses_other_settings(tmp_path):
    config = RunConfig(suites=("regression-rearrange",), agents=("random-pusher",), limit=1, backend="serial")
    run_suites(config, tmp_path, progress=False)
    with pytest.raises(ValueError, match="--resume expects the settings"):
        run_suites(RunConfig(suites=("regression-rearrange",), agents=("random-pusher",), limit=2, backend="serial"),
                   tmp_path, resume=True, progress=False)
    with pytest.raises(FileExistsError, match="--resume"):
        run_suites(config, tmp_path, progress=False)


PLUGIN = '''
import numpy as np
from agents.registry import AgentSpec, register_agent


class StopAtOnce:
    """Stops on its first step."""

    privileged = False

    def __init__(self, encoder="none"):
        self.encoder = encoder

    def reset(self, seed=None):
        pass

    def act(self, observation, info=None):
        return np.array([0, 0, 0, 0, 1], np.float32)


register_agent(AgentSpec("stop-at-once", StopAtOnce, "tabletop_rearrange", "stops at once", {"encoder": (str, "none")}))
'''


def test_user_agents_by_plugin_name_and_by_import_path_run_in_worker_processes(tmp_path, monkeypatch):
    (tmp_path / "cf_user_plugin.py").write_text(PLUGIN)
    monkeypatch.syspath_prepend(str(tmp_path))
    config = RunConfig(suites=("regression-rearrange",), agents=("stop-at-once", "cf_user_plugin:StopAtOnce"), limit=1,
                       plugins=("cf_user_plugin",), backend="process", workers=1)
    records = run_suites(config, tmp_path / "run", progress=False)
    assert sorted(r["agent"] for r in records) == ["cf_user_plugin:StopAtOnce", "stop-at-once"]
    for r in records:
        assert r["status"] == "ok", r["error"]
        assert r["metrics"]["success"] is False and r["metrics"]["steps"] == 1
        assert r["encoder"] == "oracle"  # the suite's pinned perception reaches agents that take an encoder
    with pytest.raises(ValueError, match="cannot import"):
        run_suites(RunConfig(suites=("regression-rearrange",), plugins=("no_such_plugin_module",)), tmp_path / "bad", progress=False)


CRASHER = '''
import os


class DiesInAct:
    """Kills its own process, as a segfault in native code would."""

    privileged = False

    def reset(self, seed=None):
        pass

    def act(self, observation, info=None):
        os._exit(7)
'''


def test_a_worker_that_dies_is_recorded_as_failed_and_the_run_goes_on(tmp_path, monkeypatch):
    (tmp_path / "cf_crasher.py").write_text(CRASHER)
    monkeypatch.syspath_prepend(str(tmp_path))
    config = RunConfig(suites=("regression-rearrange",), agents=("cf_crasher:DiesInAct", "random-pusher"), limit=2,
                       backend="process", workers=2)
    records = run_suites(config, tmp_path / "run", progress=False)
    crashed = [r for r in records if r["agent"] == "cf_crasher:DiesInAct"]
    assert len(crashed) == 2 and all(r["status"] == "failed" and "exit code 7" in r["error"] for r in crashed)
    assert [r["status"] for r in records if r["agent"] == "random-pusher"] == ["ok", "ok"]


def test_missing_ray_names_the_extra(monkeypatch):
    import builtins

    from harness.runner.backends import RayUnavailableError

    real_import = builtins.__import__

    def no_ray(name, *args, **kwargs):
        if name == "ray" or name.startswith("ray."):
            raise ImportError("No module named 'ray'")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_ray)
    with pytest.raises(RayUnavailableError, match=r'pip install -e "\.\[ray\]"'):
        list(run_jobs(_cheap_jobs(1), backend="ray"))


def test_an_unimportable_user_agent_fails_before_any_episode(tmp_path):
    with pytest.raises(ValueError, match="cannot import 'no_such_module_here'"):  # checked when the config is made
        config = RunConfig(suites=("regression-rearrange",), agents=("no_such_module_here:Agent",), limit=1, backend="serial")
        run_suites(config, tmp_path, progress=False)
    assert not (tmp_path / "results.jsonl").exists() or (tmp_path / "results.jsonl").stat().st_size == 0
