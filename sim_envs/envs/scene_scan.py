"""``cf/SceneScan-v0``: a scripted camera trajectory over a scene, yielding posed RGB-D frames
(MuJoCo or PyBullet)."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
from gymnasium import spaces

from conceptfusion.errors import SimError, SimTypeError
from sim_envs.envs.checks import EpisodeLifecycle, check_choice, check_fovy, check_image_size, check_int
from sim_envs.envs.rendering import LastFrameRendering, check_render_mode, frame_spaces
from sim_envs.envs.household_backends import HouseholdBackend, check_backend
from sim_envs.mujoco.scene import split_labels
from sim_envs.scenes.descriptions import answer_phrases
from sim_envs.scenes.format import Scene
from sim_envs.scenes.gen_tabletop import generate_tabletop
from sim_envs.scenes.gen_household import generate_household
from sim_envs.scenes.graph import scene_graph
from sim_envs.scenes.trajectories import scan_trajectory

__all__ = ["SceneScanEnv", "GENERATORS"]

GENERATORS = {"tabletop": generate_tabletop, "household": generate_household}
"""Scene generators by ``kind``: seed -> Scene."""


class SceneScanEnv(EpisodeLifecycle, LastFrameRendering, gym.Env):
    """Scan a scene along a scripted camera trajectory.

    **Task**: none to solve: every step moves the camera to the next pose of the trajectory
    (an orbit around the table for tabletop scenes; for household scenes a room-by-room sweep
    turning in place at 1.3 m at each room's centre, looking slightly down; see
    :func:`~sim_envs.scenes.trajectories.scan_trajectory`) and returns the
    posed RGB-D frame, for building maps and evaluating queries. The action is ignored
    (``Discrete(1)``).

    **Randomization**: the scene is generated from the reset seed by the ``kind`` generator
    (:func:`~sim_envs.scenes.gen_tabletop.generate_tabletop` or
    :func:`~sim_envs.scenes.gen_household.generate_household`), unless a fixed ``scene`` is
    given; the trajectory is fixed per scene.

    **Success**: not applicable; the episode ends (``terminated``) after the last frame. The
    ground-truth scene graph and the instance segmentation (``segmentation``: object index;
    ``furniture_segmentation``: furniture index; -1 elsewhere), ``object_ids``,
    ``object_names`` and ``object_phrases`` (per object, the sorted phrases it answers to:
    :func:`~sim_envs.scenes.descriptions.answer_phrases`) are in ``info`` for scoring and
    privileged perception, never in the observation.

    Observation (Dict): ``rgb`` (H, W, 3) uint8, ``depth`` (H, W) float32 metres (``inf``
    where nothing is hit), ``K`` (3, 3), ``cam_to_world`` (4, 4) OpenCV convention,
    ``frame`` index.

    **Simulators**: ``backend="mujoco"`` (default) or ``"pybullet"`` renders the same scene with
    the same camera conventions and labels (:mod:`sim_envs.envs.household_backends`); the
    trajectory, the scene graph's relations and the ids are the same.

    Input checks (:mod:`sim_envs.envs.checks`): ``reset`` takes no options (``None`` or ``{}``);
    ``step`` refuses any action but 0 and, once the last frame was returned, every call until
    ``reset`` (:class:`~conceptfusion.errors.EnvStateError`). Constructor arguments are
    checked: ``num_frames`` an int >= 1, ``width``/``height`` ints in [1, 8192], ``fovy_deg``
    in (0, 180), ``kind`` a key of :data:`GENERATORS`, ``scene`` ``None`` or a ``Scene``,
    ``backend`` a key of :data:`~sim_envs.envs.household_backends.HOUSEHOLD_BACKENDS`.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}
    env_name = "SceneScan"
    _renderer_attr = "_backend"  # close() releases the simulation and its camera

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
        backend: str = "mujoco",
    ) -> None:
        where = self.env_name
        self.backend = check_backend(where, backend)
        num_frames = check_int(where, "num_frames", num_frames, minimum=1)
        width, height = check_image_size(where, width, height)
        fovy_deg = check_fovy(where, fovy_deg)
        self.kind = check_choice(where, "kind", kind, GENERATORS)
        if scene is not None and not isinstance(scene, Scene):
            raise SimTypeError(f"{where}: scene: expected None or a Scene, got {type(scene).__name__}")
        self.render_mode = check_render_mode(render_mode)
        self.num_frames, self.width, self.height, self.fovy_deg = num_frames, width, height, fovy_deg
        self._fixed_scene = scene
        self.action_space = spaces.Discrete(1)
        self.observation_space = spaces.Dict(
            {
                **frame_spaces(height, width),
                "frame": spaces.Discrete(num_frames),
            }
        )
        self._backend: HouseholdBackend | None = None
        self._traj: list[tuple] = []
        self._object_phrases: list[list[str]] = []
        self._k = 0
        self._last_frame = None

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        seed, _ = self._begin_reset(seed, options)
        super().reset(seed=seed)
        scene = self._fixed_scene or GENERATORS[self.kind](int(self.np_random.integers(0, 2**31 - 1)))
        if self._backend is not None:
            self._backend.close()
            self._backend = None
        self._backend = HouseholdBackend(self.backend, scene, camera=(self.width, self.height, self.fovy_deg), labels="objects+furniture")
        self._traj = scan_trajectory(scene, self.num_frames)
        self._object_phrases = [answer_phrases(o) for o in scene.objects]
        self._k = 0
        out = self._observe()
        self._episode_started()
        return out

    def step(self, action):
        if not self.action_space.contains(action):
            raise SimError(f"SceneScan: action: expected 0 (Discrete(1)), got {action!r}")
        self._check_step()
        self._k = min(self._k + 1, self.num_frames - 1)
        obs, info = self._observe()
        terminated = self._k >= self.num_frames - 1
        self._step_done(terminated, False)
        return obs, 0.0, terminated, False, info

    def _observe(self):
        eye, target = self._traj[self._k]
        self._backend.camera.set_pose(eye, target)
        f = self._backend.camera.render()
        self._last_frame = f
        obs = {**f.observation(), "frame": self._k}
        scene = self._backend.sim.scene
        seg, seg_furniture = split_labels(f.segmentation, len(scene.objects))
        info = {
            "scene_id": scene.id,
            "segmentation": seg,
            "furniture_segmentation": seg_furniture,
            "object_ids": [o.id for o in scene.objects],
            "object_names": [o.name for o in scene.objects],
            "object_phrases": [list(p) for p in self._object_phrases],
            "furniture_ids": [p.id for p in scene.furniture],
            "scene_graph": scene_graph(self._backend.sim),
        }
        return obs, info
