"""Gymnasium environments over simulated scenes (MuJoCo, PyBullet).

Every environment is registered here, once, with a versioned id and a string entry point.

* :mod:`sim_envs.scenes` - scene and episode formats, generators, floor plans, scene graphs;
* :mod:`sim_envs.assets` - procedural objects and furniture, pybullet_data meshes, LIBERO;
* :mod:`sim_envs.mujoco` and :mod:`sim_envs.pybullet` - the two simulator backends;
* :mod:`sim_envs.envs` - the Gymnasium environments and their success functions;
* :mod:`sim_envs.cameras` - OpenGL-style camera converters into the OpenCV convention.

May import: :mod:`planners` and :mod:`conceptfusion`'s base modules (frames, cameras, errors,
names, io_utils); never an agent, a map or the harness.
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
