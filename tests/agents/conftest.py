"""Fixtures shared by the agent tests."""

import gymnasium as gym
import pytest


def _scan(seed: int, frames: int) -> list[tuple[dict, dict]]:
    import sim_envs  # noqa: F401  (registers the environments)

    env = gym.make("cf/SceneScan-v0", num_frames=frames, width=160, height=120)
    obs, info = env.reset(seed=seed)
    out = [(obs, info)]
    for _ in range(frames - 1):
        obs, _, _, _, info = env.step(0)
        out.append((obs, info))
    env.close()
    return out


@pytest.fixture(scope="session")
def tabletop_scan():
    """``(seed, frames) -> [(observation, info)]``: an orbit scan of a generated MuJoCo tabletop
    (160x120), the first frame from ``reset``."""
    return _scan
