"""``cf/ObjectSearch-v0``: drive a mobile base to an object described in words (household, in
MuJoCo or PyBullet).

The base is a kinematic unicycle, a disc of ``robot_radius`` that collides with the floor plan
(walls, doors as gaps, furniture footprints: :func:`sim_envs.scenes.floorplan.occupancy_grid`), with an
RGB-D camera at ``camera_height`` looking ``camera_pitch_deg`` down. Success and SPL follow the
object-navigation conventions (Anderson et al. 2018; VLMaps' 1 m radius).
"""

from __future__ import annotations

import math
import string
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from conceptfusion.errors import EnvStateError, SimError
from conceptfusion.names import did_you_mean
from conceptfusion.tasks import EXPLORE_GOAL
from planners.geodesic import geodesic_to_goal
from sim_envs.envs.checks import (
    EpisodeLifecycle, check_action, check_bool, check_episode, check_episode_set, check_fovy, check_image_size, check_int, check_number,
    check_scenes_root, episode_from_options,
)
from sim_envs.envs.rendering import LastFrameRendering, check_render_mode, frame_spaces
from sim_envs.envs.household_backends import HouseholdBackend, check_backend
from sim_envs.scenes.descriptions import answer_phrases
from sim_envs.scenes.episodes import Episode, EpisodeSet, resolve_scene, start_outside_message
from sim_envs.scenes.floorplan import occupancy_grid, room_plan_observation, room_plan_spaces
from sim_envs.scenes.graph import object_aabbs, scene_graph
from sim_envs.scenes.search_episodes import default_search_episodes

__all__ = ["ObjectSearchEnv", "box_distance_xy"]

_ACTION_LOW = np.array([-0.3, -1.5, 0.0], np.float32)
_ACTION_HIGH = np.array([0.6, 1.5, 1.0], np.float32)
_GOAL_CHARSET = string.ascii_letters + string.digits + " '-,."
_MAX_GOAL = 200


def box_distance_xy(xy, lo_xy, hi_xy) -> float:
    """Horizontal distance (m) from a point to an axis-aligned footprint (0 inside)."""
    d = np.maximum(np.maximum(np.asarray(lo_xy) - xy, 0.0), np.asarray(xy) - np.asarray(hi_xy))
    return float(np.linalg.norm(d))


class ObjectSearchEnv(EpisodeLifecycle, LastFrameRendering, gym.Env):
    """Find an object in an apartment from a text description, and stop next to it.

    **Task**: the observation's ``goal`` describes one object ("the red mug"). The agent drives
    the base with velocity commands and ends the episode with ``stop``.

    **Success**: ``stop`` with the base centre within ``success_distance`` (default 1.0 m,
    horizontally) of the goal object's bounding box. Also reported: SPL = success * l / max(l, p)
    with l the shortest collision-free path from the start to the success region (8-connected
    grid over the floor plan inflated by the robot radius) and p the distance the base travelled;
    the final distance to the goal; steps; collisions. Reaching ``max_steps`` truncates the
    episode as a failure.

    **Chains** (an episode with several goals, :mod:`sim_envs.scenes.chain_episodes`): the goals
    are revealed one at a time (``goal`` is the current goal's ``description``). A stop within
    the success distance of the current goal reaches it (reward 1) and reveals the next one; the
    episode goes on. A stop anywhere else ends it. Success: every goal reached; ``info`` counts
    ``goals_reached`` (in a row) of ``chain_length``; SPL uses the sum of the legs' shortest
    paths, each from where the base stopped for the previous goal. ``max_steps`` is the whole
    chain's budget.

    **Instructions** (an episode whose goal lists ``accept``, :mod:`sim_envs.scenes.instruct_episodes`):
    several objects satisfy the instruction ("something to eat"); a stop within the success
    distance of any of them succeeds, ``distance_to_goal`` is to the nearest, and SPL's shortest
    path is to the nearest success region.

    **Explore, then fetch** (an episode with ``explore_steps``): for that many steps the
    observation's ``goal`` is :data:`conceptfusion.tasks.EXPLORE_GOAL` and ``stop`` is ignored (the
    base stands still); then the first goal is revealed and the episode goes on as above, its
    SPL over the path driven from there (``info["exploring"]`` says which phase a step is in).

    **Room plan** (``room_plan=True``): the observation also holds the apartment's labelled floor
    plan, what a home robot is given at set-up (room outlines and their names; no furniture, no
    objects): ``room_boxes`` (8, 4) float32 ``[x_min, y_min, x_max, y_max]`` per room and
    ``room_types`` (8,) int64, ``k + 1`` for :data:`~conceptfusion.tasks.ROOM_TYPES` ``[k]``, 0
    for an unused row (:func:`~sim_envs.scenes.floorplan.room_plan_observation`; agents read it with
    :func:`~conceptfusion.tasks.rooms_from_plan`).

    **Actions** ``Box(3)``: ``[linear m/s in [-0.3, 0.6], angular rad/s in [-1.5, 1.5], stop]``;
    ``stop > 0.5`` ends the episode. Each step applies the command for ``control_dt`` seconds
    (10 sub-steps); out-of-range values are clipped, NaN/inf raise ``ValueError``. A sub-step that
    would bring the disc into collision is not taken (the base stops there) and counts one
    collision.

    **Observations** (Dict): ``rgb`` (H, W, 3) uint8, ``depth`` (H, W) float32 metres (inf: no
    hit), ``K`` (3, 3), ``cam_to_world`` (4, 4) OpenCV, ``base_pose`` (3,) x, y, yaw odometry,
    ``goal`` text. Ground truth (segmentation, object names, ``object_phrases``: per object the
    sorted phrases it answers to (:func:`~sim_envs.scenes.descriptions.answer_phrases`), the
    goal id, the distance to the goal; at reset also the scene graph, the free cells ``free_grid`` (H, W) bool with
    ``grid_origin`` and ``grid_cell``, the goal's box ``goal_aabb`` (2, 3) and
    ``success_distance``) is in ``info`` only; ``segmentation=False`` leaves the segmentation out
    of ``info`` and skips its render pass (for agents that never read ``info``). ``camera=False``
    renders nothing: the observations are ``base_pose`` and ``goal`` only (for agents that never
    look, such as a random walker or an oracle that reads the floor plan; the base moves and
    every metric is computed exactly as with the camera on). It needs ``segmentation=False`` and
    no ``render_mode``.

    **Episodes**: pass ``options={"episode": Episode}`` to reset (the harness does, from
    ``scenes/household/episodes-v1.jsonl``), or ``options={"episode_index": i}`` to pick the
    ``i``-th of the episode set, or neither to pick one with the reset seed. The episode set is
    ``episodes`` given to the constructor (a list of ``Episode``, an ``EpisodeSet`` or an
    ``object_search`` episode file), by default the shipped one. Scene paths are relative to
    ``scenes_root`` (default: the shipped ``scenes/`` folder).

    **Simulators**: ``backend="mujoco"`` (default) or ``"pybullet"`` builds the same apartment
    (:mod:`sim_envs.envs.household_backends`); only the rendered frames differ. The base's
    kinematics, collisions, shortest paths and success are computed from the scene description and
    the object boxes, the same in both (a goal box may differ by up to about 2 cm: MuJoCo boxes a
    library mesh in its principal axes, PyBullet boxes the object's size in its pose). A scene
    PyBullet cannot build (a broken mesh, a collision piece without volume) is refused at
    ``reset``, naming the scene file, the field and the mesh file.

    **Input checks** (:mod:`sim_envs.envs.checks`): ``reset`` options other than ``episode`` and
    ``episode_index`` (or both together) are refused, naming the nearest valid key; an episode is
    checked field by field (a goal, a finite start pose on free floor, an instruction that fits
    the ``goal`` space, a goal object the scene has). ``step`` refuses a bad action (above)
    and, once a step returned ``terminated`` or ``truncated``, every call until ``reset``
    (:class:`~conceptfusion.errors.EnvStateError`). Constructor arguments are checked:
    ``width``/``height`` ints in [1, 8192]; ``fovy_deg`` in (0, 180); ``camera_pitch_deg`` in
    (-90, 90); ``camera_height``, ``robot_radius``, ``success_distance``, ``control_dt`` finite
    and > 0; ``max_steps`` ``None`` or an int >= 1; ``scenes_root`` ``None`` or a folder;
    ``backend`` a key of :data:`~sim_envs.envs.household_backends.HOUSEHOLD_BACKENDS`.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 4}
    env_name = "ObjectSearch"
    reset_option_keys = ("episode", "episode_index")
    _renderer_attr = "_backend"  # close() releases the simulation and its camera

    def __init__(
        self,
        *,
        episodes: list[Episode] | tuple[Episode, ...] | EpisodeSet | str | None = None,
        width: int = 160,
        height: int = 120,
        fovy_deg: float = 70.0,
        camera_height: float = 1.2,
        camera_pitch_deg: float = 20.0,
        robot_radius: float = 0.25,
        success_distance: float = 1.0,
        control_dt: float = 0.5,
        max_steps: int | None = None,
        scenes_root: str | None = None,
        segmentation: bool = True,
        camera: bool = True,
        render_mode: str | None = None,
        backend: str = "mujoco",
        room_plan: bool = False,
    ) -> None:
        where = self.env_name
        self.room_plan = check_bool(where, "room_plan", room_plan)
        self.backend = check_backend(where, backend)
        check_render_mode(render_mode)
        self.segmentation = check_bool(where, "segmentation", segmentation)
        self.camera = check_bool(where, "camera", camera)
        if not self.camera and (self.segmentation or render_mode is not None):
            raise SimError(
                f"{where}: camera=False renders nothing, so it needs segmentation=False and render_mode=None; "
                f"got segmentation={self.segmentation!r}, render_mode={render_mode!r}"
            )
        width, height = check_image_size(where, width, height)
        fovy_deg = check_fovy(where, fovy_deg)
        camera_pitch_deg = check_number(where, "camera_pitch_deg", camera_pitch_deg, low=-90.0, high=90.0, low_open=True, high_open=True)
        positive = {"camera_height": camera_height, "robot_radius": robot_radius, "success_distance": success_distance, "control_dt": control_dt}
        camera_height, robot_radius, success_distance, control_dt = (
            check_number(where, name, value, low=0.0, low_open=True) for name, value in positive.items()
        )
        max_steps = check_int(where, "max_steps", max_steps, minimum=1, allow_none=True)
        scenes_root = check_scenes_root(where, scenes_root)
        episodes = check_episode_set(where, episodes, "object_search", scenes_root=scenes_root)
        self._episodes = episodes.episodes if isinstance(episodes, EpisodeSet) else episodes
        self.width, self.height, self.fovy_deg = width, height, fovy_deg
        self.camera_height, self.pitch = camera_height, math.radians(camera_pitch_deg)
        self.robot_radius, self.success_distance = robot_radius, success_distance
        self.control_dt, self._max_steps_override = control_dt, max_steps
        self.render_mode, self.scenes_root = render_mode, scenes_root
        self.action_space = spaces.Box(_ACTION_LOW, _ACTION_HIGH, dtype=np.float32)
        self.observation_space = spaces.Dict(
            {
                **(frame_spaces(height, width) if self.camera else {}),
                "base_pose": spaces.Box(-np.inf, np.inf, (3,), np.float64),
                "goal": spaces.Text(max_length=_MAX_GOAL, min_length=1, charset=_GOAL_CHARSET),
                **(room_plan_spaces() if self.room_plan else {}),
            }
        )
        self._backend: HouseholdBackend | None = None
        self._scene_key = None
        self._object_phrases: list[list[str]] = []
        self._last_frame = None
        self._pose: np.ndarray | None = None
        self._goal_box: np.ndarray | None = None
        self._accepted_boxes: list[np.ndarray] = []
        self._room_plan: dict[str, np.ndarray] = {}

    # -- episode set-up --------------------------------------------------------------------

    def _load(self, episode: Episode) -> None:
        scene = resolve_scene(episode.scene, episode.scene_seed, scenes_root=self.scenes_root)
        if not scene.rooms:
            raise SimError(f"{self.env_name}: episode {episode.episode_id!r}: scene {scene.id} is not a household scene (no rooms)")
        if self._scene_key != scene.id or self._backend is None:
            if self._backend is not None:
                self._backend.close()
                self._backend = None
            camera = (self.width, self.height, self.fovy_deg) if self.camera else None
            self._backend = HouseholdBackend(self.backend, scene, camera=camera, source=episode.scene)
            occ = occupancy_grid(scene, cell=0.05)
            self._occ, self._free = occ, occ.clearance() > self.robot_radius
            self._scene_key = scene.id
        self.scene = scene
        self._object_phrases = [answer_phrases(o) for o in scene.objects]
        if self.room_plan:
            self._room_plan = room_plan_observation(scene, f"{self.env_name}: episode {episode.episode_id!r}")

    def _is_free(self, xy) -> bool:
        occ = self._occ
        c, r = np.floor((np.asarray(xy) - occ.origin) / occ.cell).astype(int)
        h, w = self._free.shape
        return bool(0 <= r < h and 0 <= c < w and self._free[r, c])

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        seed, options = self._begin_reset(seed, options)
        super().reset(seed=seed)
        if "episode" not in options and not self._episodes:
            self._episodes = default_search_episodes().episodes
        episode = episode_from_options(self.env_name, options, self._episodes, self.np_random)
        check_episode(self.env_name, episode, charset=_GOAL_CHARSET, max_instruction=_MAX_GOAL, search=True)
        self._load(episode)
        self.episode = episode
        ids = [o.id for o in self.scene.objects]
        for k, goal in enumerate(episode.goals):
            for field_name, oid in [("", goal.object_id)] + [(".accept", a) for a in goal.accept]:
                if oid not in ids:
                    raise SimError(
                        f"{self.env_name}: episode {episode.episode_id!r}: goals[{k}]{field_name}: scene {self.scene.id} has no "
                        f"object {oid!r}{did_you_mean(oid, ids)} (objects: {', '.join(ids)})"
                    )
            if len(episode.goals) > 1:
                text = goal.description
                if not isinstance(text, str) or not 1 <= len(text) <= _MAX_GOAL or any(c not in _GOAL_CHARSET for c in text):
                    raise SimError(f"{self.env_name}: episode {episode.episode_id!r}: goals[{k}].description: a chain's goals "
                                   f"are shown one at a time, so each needs a description of 1 to {_MAX_GOAL} characters of "
                                   f"{_GOAL_CHARSET!r}; got {text!r}")
        x, y, yaw = (float(v) for v in episode.start_pose)
        outside = start_outside_message(self.scene, (x, y))
        if outside:
            raise SimError(f"{self.env_name}: episode {episode.episode_id}: {outside}")
        if not self._is_free((x, y)):
            raise SimError(f"{self.env_name}: episode {episode.episode_id}: start pose ({x:.2f}, {y:.2f}) is inside an obstacle")
        self._pose = np.array([x, y, yaw], np.float64)
        self._steps, self._path_length, self._collisions = 0, 0.0, 0
        self._goal_k, self._reached, self._shortest = 0, 0, 0.0
        self._exploring = episode.explore_steps > 0
        self._set_goal(0)
        box = self._goal_box
        self._max_steps = int(self._max_steps_override or episode.max_steps)
        obs, info = self._observe()
        info["scene_graph"] = scene_graph(self._backend.sim)
        # Ground truth for scoring and privileged agents, at reset only: the floor plan's free
        # cells for the base (inflated by the robot radius), the grid's frame and the goal's box.
        info["free_grid"] = self._free.copy()
        info["grid_origin"] = np.asarray(self._occ.origin, np.float64).copy()
        info["grid_cell"] = float(self._occ.cell)
        info["goal_aabb"] = np.asarray(box, np.float64).copy()
        info["success_distance"] = self.success_distance
        self._episode_started()
        return obs, info

    def _set_goal(self, k: int) -> None:
        """Make the episode's goal ``k`` the current one; its leg's shortest path (from the base's
        pose now) adds to the chain's."""
        ids = [o.id for o in self.scene.objects]
        goal = self.episode.goals[k]
        self._goal_k = k
        self._goal_index = ids.index(goal.object_id)
        boxes = object_aabbs(self._backend.sim)
        self._goal_box = boxes[self._goal_index]
        # the goal's object first, then those its ``accept`` adds: reaching any of them reaches the goal
        self._accepted_boxes = [self._goal_box] + [boxes[ids.index(a)] for a in goal.accept]
        cx, cy = self._occ.centres()
        region = np.zeros(cx.shape, bool)
        for box in self._accepted_boxes:
            d = np.hypot(np.maximum(np.maximum(box[0, 0] - cx, 0), cx - box[1, 0]), np.maximum(np.maximum(box[0, 1] - cy, 0), cy - box[1, 1]))
            region |= d <= self.success_distance
        self._shortest += geodesic_to_goal(self._free, self._occ.origin, self._occ.cell, tuple(self._pose[:2]), region)

    def _goal_text(self) -> str:
        """What the observation's ``goal`` says: the exploration phrase, the instruction, or a
        chain's current goal."""
        if self._exploring:
            return EXPLORE_GOAL
        if len(self.episode.goals) > 1:
            return self.episode.goals[self._goal_k].description
        return self.episode.instruction

    # -- dynamics --------------------------------------------------------------------------

    def step(self, action):
        a = check_action(self.env_name, action, 3, "[linear, angular, stop]", flatten=True)
        self._check_step()
        a = np.clip(a, _ACTION_LOW, _ACTION_HIGH)
        self._steps += 1
        stop = a[2] > 0.5 and not self._exploring
        if a[2] <= 0.5:
            sub = 10
            dt = self.control_dt / sub
            for _ in range(sub):
                x, y, yaw = self._pose
                yaw_new = math.remainder(yaw + a[1] * dt, 2 * math.pi)
                nxt = (x + a[0] * dt * math.cos(yaw), y + a[0] * dt * math.sin(yaw))
                if abs(a[0]) > 0 and not self._is_free(nxt):
                    self._collisions += 1
                    self._pose[2] = yaw_new
                    break
                self._path_length += math.dist((x, y), nxt)
                self._pose = np.array([nxt[0], nxt[1], yaw_new])
        if self._exploring and self._steps >= self.episode.explore_steps:  # the budget is spent: the first goal
            self._exploring, self._shortest, self._path_length = False, 0.0, 0.0
            self._set_goal(0)
        obs, info = self._observe()
        reached = bool(stop and info["distance_to_goal"] <= self.success_distance)
        done = stop and not (reached and self._goal_k + 1 < len(self.episode.goals))
        self._reached += reached
        if reached and not done:  # a chain: the next goal is revealed where the base stands
            self._set_goal(self._goal_k + 1)
            obs["goal"] = self._goal_text()
            info.update(self._goal_info())
            info["goal_aabb"] = np.asarray(self._goal_box, np.float64).copy()
        success = bool(reached and done)
        info["success"] = success
        info["goal_reached"] = reached
        info["goals_reached"] = self._reached
        info["spl"] = float(success * self._shortest / max(self._shortest, self._path_length, 1e-9)) if math.isfinite(self._shortest) else 0.0
        truncated = (not done) and self._steps >= self._max_steps
        self._step_done(done, truncated)
        return obs, float(reached), bool(done), bool(truncated), info

    # -- sensing ---------------------------------------------------------------------------

    @property
    def goal_box(self) -> np.ndarray:
        """The current goal object's axis-aligned box in the world frame (metres), set by ``reset``.

        Shape: ``(2, 3)``: ``[[x_min, y_min, z_min], [x_max, y_max, z_max]]``.
        """
        if self._goal_box is None:
            raise EnvStateError(f"{self.env_name}: goal_box needs an episode; call reset() first")
        return self._goal_box

    def camera_eye_target(self, pose=None) -> tuple[np.ndarray, np.ndarray]:
        """Camera position and look-at point for a base pose ``(x, y, yaw)`` (default: the
        current one, which needs a reset)."""
        if pose is None and self._pose is None:
            raise EnvStateError(f"{self.env_name}: camera_eye_target() without a pose needs an episode; call reset() first")
        x, y, yaw = self._pose if pose is None else pose
        eye = np.array([x, y, self.camera_height])
        fwd = np.array([math.cos(yaw) * math.cos(self.pitch), math.sin(yaw) * math.cos(self.pitch), -math.sin(self.pitch)])
        return eye, eye + fwd

    def _observe(self):
        frame = {}
        if self.camera:
            self._backend.camera.set_pose(*self.camera_eye_target())
            f = self._backend.camera.render(segmentation=self.segmentation)
            self._last_frame = f
            frame = f.observation()
        obs = {**frame, "base_pose": self._pose.copy(), "goal": self._goal_text(),
               **{k: v.copy() for k, v in self._room_plan.items()}}
        info = {
            "episode_id": self.episode.episode_id,
            "scene_id": self.scene.id,
            **({"segmentation": f.segmentation} if self.segmentation else {}),
            "object_ids": [o.id for o in self.scene.objects],
            "object_names": [o.name for o in self.scene.objects],
            "object_phrases": [list(p) for p in self._object_phrases],
            **self._goal_info(),
            "path_length": self._path_length,
            "steps": self._steps,
            "collisions": self._collisions,
            "success": False,
            "spl": 0.0,
            "goals_reached": self._reached,
            "chain_length": len(self.episode.goals),
            "exploring": self._exploring,
        }
        return obs, info

    def _goal_info(self) -> dict:
        """The current goal's entries of ``info``: its object id, index in the chain, the base's
        distance to it and the shortest path so far."""
        return {
            "goal_object_id": self.episode.goals[self._goal_k].object_id,
            "goal_index": self._goal_k,
            "distance_to_goal": min(box_distance_xy(self._pose[:2], b[0, :2], b[1, :2]) for b in self._accepted_boxes),
            "shortest_path_length": self._shortest,
        }
