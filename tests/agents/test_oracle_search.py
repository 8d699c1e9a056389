"""The privileged scripted searcher: geodesic field, descent, and the shipped episodes are solvable."""

import numpy as np
import pytest

from agents.oracle_search import OracleSearchAgent, descend
from harness.runner.tasks import EpisodeJob, run_episode
from planners.geodesic import geodesic_field
from sim_envs.scenes.search_episodes import default_search_episodes


def test_field_goes_around_a_wall_and_descent_reaches_the_goal():
    free = np.ones((10, 10), bool)
    free[0:8, 5] = False  # a wall with a gap at the bottom rows 8-9
    goal = np.zeros_like(free)
    goal[0, 9] = True
    field = geodesic_field(free, goal, 0.1)
    assert np.isinf(field[0, 5]) and field[0, 9] == 0.0
    assert field[0, 0] > 0.9 + 0.4  # around the wall, much longer than the straight 0.9 m
    cells = descend(field, (0, 0))
    assert cells[0] == (0, 0) and cells[-1] == (0, 9)
    assert all(free[r, c] for r, c in cells) and any(r >= 8 for r, _ in cells)
    assert all(max(abs(r1 - r0), abs(c1 - c0)) == 1 for (r0, c0), (r1, c1) in zip(cells, cells[1:]))
    assert descend(geodesic_field(free, np.zeros_like(free), 0.1), (0, 0)) == []


def test_needs_info():
    with pytest.raises(ValueError, match="privileged"):
        OracleSearchAgent().act({"base_pose": np.zeros(3)}, None)


def test_oracle_solves_the_shipped_search_episodes():
    episodes = default_search_episodes().episodes
    recs = [run_episode(EpisodeJob("t", "search", "object_search", "oracle-searcher", {}, ep, 0, {"width": 32, "height": 24}))
            for ep in episodes]
    assert all(r["status"] == "ok" for r in recs), [r["error"] for r in recs if r["status"] != "ok"]
    rate = sum(r["metrics"]["success"] for r in recs) / len(recs)
    assert rate > 0.9
    spl = np.mean([r["metrics"]["spl"] for r in recs if r["metrics"]["success"]])
    assert spl > 0.7  # near-shortest paths
