"""Every registered environment id builds through ``gymnasium.make`` and passes the checker."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import sim_envs

SMALL = {
    "cf/SceneScan-v0": {"width": 64, "height": 48},
    "cf/TabletopRearrange-v0": {"width": 64, "height": 48, "scan_frames": 3, "scan_width": 48, "scan_height": 36},
    "cf/ObjectSearch-v0": {"width": 64, "height": 48},
}


def test_every_id_has_small_settings():
    assert set(SMALL) == set(sim_envs.ENV_IDS)


@pytest.mark.parametrize("env_id", sim_envs.ENV_IDS)
def test_registered_env_passes_the_checker(env_id):
    env = gym.make(env_id, **SMALL[env_id])
    try:
        check_env(env.unwrapped, skip_render_check=True)
    finally:
        env.close()


@pytest.mark.parametrize("env_id, extra", [
    ("cf/SceneScan-v0", {"kind": "household", "num_frames": 6}),
    ("cf/ObjectSearch-v0", {}),
])
def test_household_envs_pass_the_checker_on_pybullet(env_id, extra):
    pytest.importorskip("pybullet")
    if env_id == "cf/SceneScan-v0":  # a shipped apartment: generating one per reset is slow
        from sim_envs.scenes.episodes import SCENES_ROOT
        from sim_envs.scenes.format import load_scene

        extra = {**extra, "scene": load_scene(SCENES_ROOT / "household" / "household-0000.json")}
    env = gym.make(env_id, **SMALL[env_id], **extra, backend="pybullet")
    try:
        assert env.unwrapped.backend == "pybullet"
        check_env(env.unwrapped, skip_render_check=True)
        obs, _ = env.reset(seed=1)
        assert np.isfinite(obs["depth"]).mean() > 0.5  # the PyBullet camera sees the apartment
    finally:
        env.close()


def test_rearrange_scan_frames_are_posed_and_labelled():
    env = gym.make("cf/TabletopRearrange-v0", **SMALL["cf/TabletopRearrange-v0"])
    obs, info = env.reset(seed=3)
    assert obs["scan_rgb"].shape == (3, 36, 48, 3) and obs["scan_depth"].shape == (3, 36, 48)
    assert obs["scan_K"].shape == (3, 3, 3) and obs["scan_cam_to_world"].shape == (3, 4, 4)
    assert info["scan_segmentation"].shape == (3, 36, 48)
    # the orbit sees the table from different places; every view sees some object
    centres = obs["scan_cam_to_world"][:, :3, 3]
    assert np.min(np.linalg.norm(centres[1:] - centres[0], axis=1)) > 0.1
    assert all((seg >= 0).any() for seg in info["scan_segmentation"])
    assert obs["line"].shape == (2, 2) and np.linalg.norm(obs["line"][1] - obs["line"][0]) > 0.1
    env.close()
