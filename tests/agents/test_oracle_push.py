"""The privileged oracle pusher solves shipped tabletop episodes."""

from pathlib import Path

import numpy as np
import pytest

from agents.oracle_push import OraclePushAgent, footprint_corners
from sim_envs.scenes.episodes import load_episodes
from sim_envs.envs.tabletop_rearrange import TabletopRearrangeEnv

SHIPPED = Path(__file__).resolve().parents[2] / "scenes" / "tabletop" / "episodes-v1.jsonl"


def test_oracle_solves_shipped_episodes():
    env = TabletopRearrangeEnv(episodes=load_episodes(SHIPPED), width=32, height=24)
    agent = OraclePushAgent()
    assert agent.privileged is True
    wins = 0
    for i in range(8):
        obs, info = env.reset(seed=i, options={"episode_index": i})
        agent.reset(seed=i)
        done = False
        while not done:
            obs, reward, terminated, truncated, info = env.step(agent.act(obs, info))
            done = terminated or truncated
        wins += reward > 0
    env.close()
    assert wins >= 7


def test_oracle_needs_ground_truth():
    with pytest.raises(ValueError, match="privileged"):
        OraclePushAgent().act({}, None)


def test_footprint_of_a_turned_box():
    pose = np.array([0.1, 0.2, 0.4, np.cos(np.pi / 4), 0, 0, np.sin(np.pi / 4)])  # yaw 90 degrees
    corners, axes = footprint_corners(pose, (0.2, 0.1, 0.05))
    assert np.allclose(corners.min(axis=0), [0.05, 0.1]) and np.allclose(corners.max(axis=0), [0.15, 0.3])
    assert len(axes) == 2  # the vertical axis projects to a point
