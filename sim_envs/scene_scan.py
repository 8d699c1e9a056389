"""``cf/SceneScan-v0``: a scripted camera trajectory over a scene, yielding posed RGB-D frames."""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from sim_envs.mujoco_camera import MujocoRGBDCamera
from sim_envs.mujoco_scene import build_mujoco
from sim_envs.scene_format import Scene
from sim_envs.scene_gen import generate_tabletop
from sim_envs.scene_graph import scene_graph

__all__ = ["SceneScanEnv", "orbit_trajectory"]


def orbit_trajectory(scene: Scene, num_frames: int, *, radius: float = 1.1, height: float = 0.75) -> list[tuple]:
    """(eye, target) pairs on a circle around the table, looking at its centre."""
    if scene.table is None:
        raise ValueError(f"scene {scene.id}: an orbit needs a table to circle")
    cx, cy, _ = scene.table.center
    target = (cx, cy, scene.table.top_z)
    out = []
    for k in range(num_frames):
        a = 2 * math.pi * k / num_frames - math.pi / 2
        out.append(((cx + radius * math.cos(a), cy + radius * math.sin(a), scene.table.top_z + height), target))
    return out


class SceneScanEnv(gym.Env):
    """Scan a scene along a scripted camera trajectory.

    **Task**: none to solve: every step moves the camera to the next pose of the trajectory
    (an orbit around the table for tabletop scenes) and returns the posed RGB-D frame, for
    building maps and evaluating queries. The action is ignored (``Discrete(1)``).

    **Randomization**: the scene is generated from the reset seed
    (:func:`~sim_envs.scene_gen.generate_tabletop`), unless a fixed ``scene`` is given; the
    trajectory is fixed per scene.

    **Success**: not applicable; the episode ends (``terminated``) after the last frame. The
    ground-truth scene graph and the instance segmentation are in ``info`` for scoring, never
    in the observation.

    Observation (Dict): ``rgb`` (H, W, 3) uint8, ``depth`` (H, W) float32 metres (``inf``
    where nothing is hit), ``K`` (3, 3), ``cam_to_world`` (4, 4) OpenCV convention,
    ``frame`` index.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(
        self,
        *,
        num_frames: int = 24,
        width: int = 320,
        height: int = 240,
        fovy_deg: float = 60.0,
        scene: Scene | None = None,
        render_mode: str | None = None,
    ) -> None:
        if num_frames < 1:
            raise ValueError(f"num_frames: expected at least 1, got {num_frames}")
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode: expected None or 'rgb_array', got {render_mode!r}")
        self.num_frames, self.width, self.height, self.fovy_deg = int(num_frames), int(width), int(height), float(fovy_deg)
        self.render_mode = render_mode
        self._fixed_scene = scene
        self.action_space = spaces.Discrete(1)
        self.observation_space = spaces.Dict(
            {
                "rgb": spaces.Box(0, 255, (height, width, 3), np.uint8),
                "depth": spaces.Box(0.0, np.inf, (height, width), np.float32),
                "K": spaces.Box(-np.inf, np.inf, (3, 3), np.float64),
                "cam_to_world": spaces.Box(-np.inf, np.inf, (4, 4), np.float64),
                "frame": spaces.Discrete(num_frames),
            }
        )
        self._sim = None
        self._camera: MujocoRGBDCamera | None = None
        self._traj: list[tuple] = []
        self._k = 0
        self._last = None

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        scene = self._fixed_scene or generate_tabletop(int(self.np_random.integers(0, 2**31 - 1)))
        if self._camera is not None:
            self._camera.close()
        self._sim = build_mujoco(scene)
        self._camera = MujocoRGBDCamera(
            self._sim.model, self._sim.data, self.width, self.height, fovy_deg=self.fovy_deg, geom_object=self._sim.geom_object
        )
        self._traj = orbit_trajectory(scene, self.num_frames)
        self._k = 0
        return self._observe()

    def step(self, action):
        if self._sim is None:
            raise RuntimeError("SceneScan: call reset() before step()")
        if not self.action_space.contains(action):
            raise ValueError(f"SceneScan: expected action 0 (Discrete(1)), got {action!r}")
        self._k = min(self._k + 1, self.num_frames - 1)
        obs, info = self._observe()
        terminated = self._k >= self.num_frames - 1
        return obs, 0.0, terminated, False, info

    def _observe(self):
        eye, target = self._traj[self._k]
        self._camera.set_pose(eye, target)
        f = self._camera.render()
        self._last = f
        obs = {"rgb": f.rgb, "depth": f.depth, "K": f.K, "cam_to_world": f.cam_to_world, "frame": self._k}
        scene = self._sim.scene
        info = {
            "scene_id": scene.id,
            "segmentation": f.segmentation,
            "object_ids": [o.id for o in scene.objects],
            "object_names": [o.name for o in scene.objects],
            "scene_graph": scene_graph(self._sim),
        }
        return obs, info

    def render(self):
        if self.render_mode == "rgb_array" and self._last is not None:
            return self._last.rgb
        return None

    def close(self) -> None:
        if self._camera is not None:
            self._camera.close()
            self._camera = None
