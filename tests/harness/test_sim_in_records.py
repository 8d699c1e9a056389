"""Every record says which simulator ran it; ``search-v2-pybullet`` runs search-v2's episodes in
PyBullet."""

from __future__ import annotations

import pytest

from harness.runner.suites import DEFAULT_SUITES, get_suite, suite_episodes
from harness.runner.tasks import EpisodeJob, close_cached_envs, run_episode

pytest.importorskip("pybullet")


def test_the_pybullet_variant_is_search_v2_on_pybullet_and_not_a_default():
    base, variant = get_suite("search-v2"), get_suite("search-v2-pybullet")
    assert variant.env_kwargs == {**base.env_kwargs, "backend": "pybullet"}
    assert [e.episode_id for e in suite_episodes(variant)] == [e.episode_id for e in suite_episodes(base)]
    assert "search-v2-pybullet" not in DEFAULT_SUITES


@pytest.mark.parametrize("suite, backend, sim", [
    ("search-v2", None, "mujoco"),
    ("search-v2-pybullet", "pybullet", "pybullet"),
    ("rearrange-v2", None, "mujoco"),
])
def test_records_name_the_simulator(suite, backend, sim):
    s = get_suite(suite)
    episode = suite_episodes(s)[0]
    env = {"width": 64, "height": 48, **({"backend": backend} if backend else {})}
    if s.task == "tabletop_rearrange":
        env["scan_frames"] = 0
    agent = "random-walker" if s.task == "object_search" else "random-pusher"
    job = EpisodeJob(run_id="t", suite=suite, task=s.task, agent=agent, agent_kwargs={}, episode=episode, env_kwargs=env)
    try:
        record = run_episode(job)
    finally:
        close_cached_envs()
    assert record["status"] == "ok", record.get("error")
    assert record["extras"]["sim"] == sim


def test_a_failed_episode_names_its_simulator_too():
    s = get_suite("search-v2-pybullet")
    job = EpisodeJob(run_id="t", suite=s.name, task=s.task, agent="no-such-agent", agent_kwargs={},
                     episode=suite_episodes(s)[0], env_kwargs=dict(s.env_kwargs))
    record = run_episode(job)
    assert record["status"] == "failed" and record["extras"]["sim"] == "pybullet"
