"""Agents that never read part of the observation do not get it rendered (tabletop agents that
never read the orbit scan, search agents that never look), and their episodes are unchanged."""

import pytest

from agents.registry import make_agent
from harness.runner import tasks
from harness.runner.run import RunConfig, episode_jobs
from harness.runner.suites import get_suite
from harness.runner.tasks import close_cached_envs, run_episode


def _jobs(agent: str, limit: int = 2, suite: str = "regression-rearrange"):
    suite = get_suite(suite)
    return episode_jobs(suite, RunConfig(suites=(suite.name,), agents=(agent,), limit=limit, backend="serial"), "t")


def _outcome(rec):
    return rec["status"], rec["metrics"], rec["category"], rec["extras"]


def _everything_rendered(task, kwargs, agent, **_):
    """``env_kwargs_for`` as it was before agents could decline the scan or the camera."""
    return {"segmentation": bool(agent.privileged), **kwargs}


@pytest.mark.parametrize("agent, reads", [("map-pusher", True), ("frame-pusher", False), ("random-pusher", False),
                                          ("oracle-pusher", False)])
def test_only_agents_that_read_the_scan_get_one(agent, reads):
    job = _jobs(agent, 1)[0]
    assert job.env_kwargs["scan_frames"] == 6
    built = make_agent(job.agent, **job.agent_kwargs)
    assert getattr(built, "reads_scan", True) is reads
    assert tasks.env_kwargs_for(job.task, job.env_kwargs, built)["scan_frames"] == (6 if reads else 0)


def test_an_agent_without_the_attribute_keeps_the_scan():
    class Plain:
        privileged = False

    job = _jobs("random-pusher", 1)[0]
    assert tasks.env_kwargs_for(job.task, job.env_kwargs, Plain())["scan_frames"] == 6


@pytest.mark.parametrize("agent", ["frame-pusher", "oracle-pusher"])
def test_leaving_the_scan_out_changes_no_record(agent, monkeypatch):
    try:
        without = [_outcome(run_episode(j)) for j in _jobs(agent)]
        close_cached_envs()
        # the same episodes with the scan rendered
        monkeypatch.setattr(tasks, "env_kwargs_for", _everything_rendered)
        with_scan = [_outcome(run_episode(j)) for j in _jobs(agent)]
    finally:
        close_cached_envs()
    assert all(status == "ok" for status, *_ in without)
    assert without == with_scan


@pytest.mark.parametrize("agent, looks", [("map-navigator", True), ("frame-searcher", True), ("random-walker", False),
                                          ("oracle-searcher", False)])
def test_only_search_agents_that_look_get_a_camera(agent, looks):
    job = _jobs(agent, 1, "regression-search")[0]
    built = make_agent(job.agent, **job.agent_kwargs)
    assert getattr(built, "reads_images", True) is looks
    kwargs = tasks.env_kwargs_for(job.task, job.env_kwargs, built)
    assert kwargs.get("camera", True) is looks and kwargs["segmentation"] is (looks and built.privileged)
    # a recorded episode keeps its frames for the replay, and a suite's own setting wins
    assert "camera" not in tasks.env_kwargs_for(job.task, job.env_kwargs, built, records=True)
    assert tasks.env_kwargs_for(job.task, {**job.env_kwargs, "camera": True}, built)["camera"] is True


@pytest.mark.parametrize("agent", ["random-walker", "oracle-searcher"])
def test_leaving_the_camera_out_changes_no_record(agent, monkeypatch):
    try:
        blind = [_outcome(run_episode(j)) for j in _jobs(agent, 2, "regression-search")]
        search_envs = [env for key, env in tasks._ENV_CACHE.items() if key[0] == "object_search"]
        assert search_envs and not any(env.unwrapped.camera for env in search_envs)
        close_cached_envs()
        monkeypatch.setattr(tasks, "env_kwargs_for", _everything_rendered)
        seeing = [_outcome(run_episode(j)) for j in _jobs(agent, 2, "regression-search")]
    finally:
        close_cached_envs()
    assert all(status == "ok" for status, *_ in blind)
    assert blind == seeing
