"""The navigator's bump rule: a base pushed against something its map does not show backs off,
marks the spot and plans around it; with the rule off (the default) it keeps pushing."""

from __future__ import annotations

import math

import numpy as np
import pytest

from agents.navigator import MapNavigator, NavigatorConfig
from tests.agents.test_navigator_approach import GOAL, _StaticMapper, _world

HIDDEN = np.array([1.8, -0.25])
"""Centre of an obstacle the simulated base collides with but the map never shows."""
HIDDEN_RADIUS = 0.3
ROBOT_RADIUS = 0.25


def _drive_with_hidden_obstacle(agent: MapNavigator, steps: int = 200, dt: float = 0.5) -> tuple[np.ndarray, bool, int]:
    """Unicycle rollout from (0.5, 0) facing the goal; a move that would overlap the hidden
    obstacle is refused (the base stays put). Returns the pose, whether it stopped, and how many
    steps it spent pressed against the obstacle."""
    pose, pressed = np.array([0.5, 0.0, 0.0]), 0
    for _ in range(steps):
        action = agent.act({"base_pose": pose.copy(), "goal": "the basket"})
        if action[2] > 0.5:
            return pose, True, pressed
        blocked = False
        for _ in range(10):
            nxt = pose.copy()
            nxt[0] += float(action[0]) * dt / 10 * math.cos(pose[2])
            nxt[1] += float(action[0]) * dt / 10 * math.sin(pose[2])
            nxt[2] = math.remainder(pose[2] + float(action[1]) * dt / 10, 2 * math.pi)
            if np.linalg.norm(nxt[:2] - HIDDEN) < ROBOT_RADIUS + HIDDEN_RADIUS:
                nxt[:2] = pose[:2]
                blocked = blocked or float(action[0]) > 0
            pose = nxt
        pressed += blocked
    return pose, False, pressed


def test_without_the_rule_the_base_keeps_pushing():
    agent = MapNavigator(_StaticMapper(_world(0.3)), NavigatorConfig())
    _, stopped, pressed = _drive_with_hidden_obstacle(agent)
    assert not stopped and pressed > 150


def test_the_bump_rule_gets_round_what_the_map_does_not_show():
    agent = MapNavigator(_StaticMapper(_world(0.3)), NavigatorConfig(stuck_steps=3))
    pose, stopped, pressed = _drive_with_hidden_obstacle(agent)
    assert stopped and np.linalg.norm(pose[:2] - GOAL) <= 1.0
    assert any("stuck at" in line for line in agent.log) and pressed < 30


@pytest.mark.parametrize("kwargs", [{"stuck_steps": -1}, {"stuck_steps": 2.5}, {"backoff_steps": True}, {"stuck_move": -0.1}])
def test_bad_bump_settings(kwargs):
    with pytest.raises(ValueError, match=next(iter(kwargs))):
        NavigatorConfig(**kwargs)
