"""``cf/SceneScan-v0``: a scripted camera trajectory over a scene, yielding posed RGB-D frames."""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from sim_envs.mujoco.camera import MujocoRGBDCamera
from sim_envs.mujoco.scene import build_mujoco, split_labels
from sim_envs.scenes.format import Scene
from sim_envs.scenes.gen_tabletop import generate_tabletop
from sim_envs.scenes.gen_household import generate_household
from sim_envs.scenes.graph import scene_graph

__all__ = ["SceneScanEnv", "orbit_trajectory", "room_sweep_trajectory", "scan_trajectory", "GENERATORS"]

GENERATORS = {"tabletop": generate_tabletop, "household": generate_household}
"""Scene generators by ``kind``: seed -> Scene."""


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


def room_sweep_trajectory(
    scene: Scene, num_frames: int, *, height: float = 1.3, pitch_deg: float = -22.0, offset: float = 0.0
) -> list[tuple]:
    """(eye, target) pairs turning in place at each room's centre, room after room.

    ``num_frames`` is spread over the rooms (the first rooms get one more when it does not
    divide); in each room the camera, ``height`` metres up, turns through 360 degrees looking
    ``pitch_deg`` below the horizon (negative: down). ``offset`` shifts the start heading.
    """
    if not scene.rooms:
        raise ValueError(f"scene {scene.id}: a room sweep needs rooms; this scene has none")
    n_rooms = len(scene.rooms)
    if num_frames < n_rooms:
        raise ValueError(f"num_frames: expected at least one frame per room ({n_rooms}), got {num_frames}")
    drop = math.tan(math.radians(-pitch_deg))
    out = []
    for k, room in enumerate(scene.rooms):
        n = num_frames // n_rooms + (1 if k < num_frames % n_rooms else 0)
        cx, cy = room.center
        for i in range(n):
            a = offset + 2 * math.pi * i / n
            out.append(((cx, cy, height), (cx + math.cos(a), cy + math.sin(a), height - drop)))
    return out


def scan_trajectory(scene: Scene, num_frames: int) -> list[tuple]:
    """The scan of a scene: a room sweep for household scenes, an orbit around the table otherwise."""
    return room_sweep_trajectory(scene, num_frames) if scene.rooms else orbit_trajectory(scene, num_frames)


class SceneScanEnv(gym.Env):
    """Scan a scene along a scripted camera trajectory.

    **Task**: none to solve: every step moves the camera to the next pose of the trajectory
    (an orbit around the table for tabletop scenes; for household scenes a room-by-room sweep
    turning in place at 1.3 m at each room's centre, looking slightly down) and returns the
    posed RGB-D frame, for building maps and evaluating queries. The action is ignored
    (``Discrete(1)``).

    **Randomization**: the scene is generated from the reset seed by the ``kind`` generator
    (:func:`~sim_envs.scenes.gen_tabletop.generate_tabletop` or
    :func:`~sim_envs.scenes.gen_household.generate_household`), unless a fixed ``scene`` is
    given; the trajectory is fixed per scene.

    **Success**: not applicable; the episode ends (``terminated``) after the last frame. The
    ground-truth scene graph and the instance segmentation (``segmentation``: object index;
    ``furniture_segmentation``: furniture index; -1 elsewhere) are in ``info`` for scoring,
    never in the observation.

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
        kind: str = "tabletop",
        render_mode: str | None = None,
    ) -> None:
        if num_frames < 1:
            raise ValueError(f"num_frames: expected at least 1, got {num_frames}")
        if kind not in GENERATORS:
            import difflib

            close = difflib.get_close_matches(str(kind), GENERATORS, n=2)
            raise ValueError(f"kind: expected one of {sorted(GENERATORS)}, got {kind!r}" + (f"; did you mean {close[0]!r}?" if close else ""))
        self.kind = kind
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
        scene = self._fixed_scene or GENERATORS[self.kind](int(self.np_random.integers(0, 2**31 - 1)))
        if self._camera is not None:
            self._camera.close()
        self._sim = build_mujoco(scene)
        self._camera = MujocoRGBDCamera(
            self._sim.model, self._sim.data, self.width, self.height, fovy_deg=self.fovy_deg, geom_object=self._sim.geom_labels()
        )
        self._traj = scan_trajectory(scene, self.num_frames)
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
        seg, seg_furniture = split_labels(f.segmentation, len(scene.objects))
        info = {
            "scene_id": scene.id,
            "segmentation": seg,
            "furniture_segmentation": seg_furniture,
            "object_ids": [o.id for o in scene.objects],
            "object_names": [o.name for o in scene.objects],
            "furniture_ids": [p.id for p in scene.furniture],
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
