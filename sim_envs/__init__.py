"""Gymnasium environments over simulated scenes (MuJoCo, PyBullet).

Every environment is registered here, once, with a versioned id and a string entry point.
"""

from gymnasium.envs.registration import register, registry

__all__ = ["ENV_IDS"]

ENV_IDS = ("cf/SceneScan-v0", "cf/TabletopRearrange-v0", "cf/ObjectSearch-v0")

if "cf/SceneScan-v0" not in registry:
    register(id="cf/SceneScan-v0", entry_point="sim_envs.envs.scene_scan:SceneScanEnv")
if "cf/TabletopRearrange-v0" not in registry:
    register(id="cf/TabletopRearrange-v0", entry_point="sim_envs.envs.tabletop_rearrange:TabletopRearrangeEnv")
if "cf/ObjectSearch-v0" not in registry:
    register(id="cf/ObjectSearch-v0", entry_point="sim_envs.envs.object_search:ObjectSearchEnv")
