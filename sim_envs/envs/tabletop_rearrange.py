"""``cf/TabletopRearrange-v0``: push named objects to a named side of a yellow line on a table."""

from __future__ import annotations

import importlib
import os
import string
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from conceptfusion.errors import SimError, SimTypeError
from sim_envs.scenes.episodes import MAX_LINE_DISTANCE, Episode, EpisodeSet, resolve_scene, tabletop_goals, tabletop_instruction
from conceptfusion.frames import RGBDFrame
from sim_envs.envs.checks import (
    EpisodeLifecycle, check_action, check_bool, check_choice, check_episode, check_episode_set, check_fovy, check_image_size, check_int,
    check_scenes_root, episode_from_options,
)
from sim_envs.envs.rearrange_eval import VIEW_DIR, RearrangeResult, evaluate, line_normal
from sim_envs.envs.rendering import LastFrameRendering, check_render_mode, frame_spaces
from sim_envs.envs.tabletop_sim import TabletopSim
from sim_envs.scenes.descriptions import answer_phrases
from sim_envs.scenes.format import Scene
from sim_envs.scenes.gen_tabletop import generate_tabletop
from sim_envs.scenes.graph import scene_graph
from sim_envs.scenes.trajectories import orbit_trajectory

__all__ = ["TabletopRearrangeEnv", "BACKENDS", "make_backend", "ACTION_LOW", "ACTION_HIGH", "camera_pose"]

BACKENDS = {
    "mujoco": "sim_envs.mujoco.tabletop:MujocoTabletop",
    "pybullet": "sim_envs.pybullet.tabletop:PyBulletTabletop",
}
"""Simulation backends by name (``module:class``, imported when first used)."""

ACTION_LOW = np.array([-0.6, -0.4, -np.pi, 0.0, 0.0], np.float32)
ACTION_HIGH = np.array([0.6, 0.4, np.pi, 0.5, 1.0], np.float32)
"""Action bounds: start x, start y (the 1.2 x 0.8 m table top), direction (rad), distance (m), stop."""

INSTRUCTION_CHARSET = string.ascii_letters + string.digits + " ,.'-"
_MAX_INSTRUCTION = 256


def _backend_entry(name: str) -> str:
    return BACKENDS[check_choice("TabletopRearrange", "backend", name, BACKENDS)]


def make_backend(name: str, scene: Scene, seed: int = 0) -> TabletopSim:
    """The simulation backend ``name`` (see :data:`BACKENDS`) with ``scene`` loaded."""
    module, cls = _backend_entry(name).split(":")
    try:
        mod = importlib.import_module(module)
    except ModuleNotFoundError as exc:
        raise ModuleNotFoundError(f"backend {name!r} is not available: {exc}") from exc
    return getattr(mod, cls)(scene, seed=seed)


def camera_pose(scene: Scene) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """(eye, target) of the fixed observation camera: in front of the table (-y side), looking
    down at its centre at about 50 degrees, facing +y (the viewer of "left" and "right")."""
    cx, cy, _ = scene.table.center
    top = scene.table.top_z
    return (cx, cy - 0.72, top + 0.85), (cx, cy + 0.04, top)


class TabletopRearrangeEnv(EpisodeLifecycle, LastFrameRendering, gym.Env):
    """Push named objects across a dividing line on a table.

    **Task**: the instruction (e.g. ``"push the red mug to the right of the line"``) names one
    or two target objects and, for each, the side of the yellow line it must end on; every target
    starts on the other side. Left and right are as seen from the observation camera, which
    stands in front of the table and faces +y (so "right" is +x for the shipped scenes).

    **Actions**: ``Box(5)`` float32 ``(start_x, start_y, direction_rad, distance, stop)``: a
    straight push primitive (the fingertip comes down from above at ``(start_x, start_y)``,
    2 cm above the table top, pushes ``distance`` metres along world yaw ``direction_rad`` and
    lifts). Bounds: x in [-0.6, 0.6], y in [-0.4, 0.4] (the table top), distance in [0, 0.5];
    out-of-bounds x, y, distance and stop are clipped to them and the direction is wrapped into
    [-pi, pi); NaN or infinite components raise ``ValueError``. ``stop > 0.5`` ends the episode
    without pushing. A push whose start point is off the table or inside an object's footprint
    is not executed (``info["last_push"]`` says why) but still costs a step.

    **Observation** (Dict): a posed RGB-D frame from the fixed overhead-oblique camera (``rgb``
    (H, W, 3) uint8, ``depth`` (H, W) float32 metres, ``inf`` where nothing is hit, ``K`` (3, 3),
    ``cam_to_world`` (4, 4) OpenCV), the ``instruction`` text and the painted ``line``'s two
    endpoints (2, 2) (world x, y on the table top; part of the task statement, as the line is in
    the paper's set-up). No ground truth.

    **Scanning**: with ``scan_frames=n > 0`` every observation also carries an orbit scan of the
    table in the current state, ``scan_rgb`` (n, h, w, 3), ``scan_depth`` (n, h, w),
    ``scan_K`` (n, 3, 3) and ``scan_cam_to_world`` (n, 4, 4) (``h, w`` = ``scan_height,
    scan_width``, default the observation size): what a wrist or head camera sweeping the table
    before each push would see; map-equipped agents fuse it. :meth:`scan` returns such frames on
    demand without stepping the episode.

    **Randomization**: an episode record (``episodes=`` file or set; ``reset(options={"episode":
    ...})`` or ``{"episode_index": i}``; otherwise one drawn with the reset seed) fixes the scene
    and the instruction (a record naming the id of the ``scene=`` given to the constructor uses
    it). Version 2 files (``scenes/tabletop-v2/episodes-v2.jsonl``: object-library scenes, goals
    named by name, synonym, attribute or function, the description kind recorded per goal) work
    as they are: observation, actions and success are the same. Without records the scene is
    generated from the reset seed
    (:func:`~sim_envs.scenes.gen_tabletop.generate_tabletop`) and 1-2 targets are drawn with it among the
    objects within 0.25 m of the line.

    **Success** (:func:`~sim_envs.envs.rearrange_eval.evaluate`): every target's centre (its box centre) is on
    the table and at least 2 cm past the line on its instructed side, and every other object moved
    less than 5 cm horizontally from its start. The episode terminates on ``stop`` and is
    truncated after ``max_steps`` steps (default 6); the reward is sparse: 1.0 on the final step
    if success holds then, else 0.

    ``info`` (ground truth, for scoring and privileged agents only): ``segmentation``,
    ``object_ids``, ``object_names``, ``object_phrases`` (per object, the sorted phrases it
    answers to: :func:`~sim_envs.scenes.descriptions.answer_phrases`), ``object_poses`` (n, 7), ``object_aabbs`` (n, 2, 3),
    ``object_sizes`` (n, 3) (box size in the object frame, base at its origin; these three are
    nested lists, since n varies between scenes and vector envs batch array-valued info),
    ``scan_segmentation`` (n, h, w) int32 (with ``scan_frames``; ``segmentation=False`` leaves out
    both segmentations and their render pass, for agents that never read ``info``),
    ``target_ids``, ``target_sides``, ``line``, ``right_normal``, ``view_dir``, ``table_xy`` (2, 2)
    (lower, upper table corner), ``scene_graph`` (MuJoCo backend; ``None`` otherwise), ``last_push``,
    ``evaluation``, ``success``, ``steps``, ``episode_id``, ``scene_id``.

    **Input checks** (:mod:`sim_envs.envs.checks`): ``reset`` options are ``None`` or a dict
    with ``"episode"`` (an :class:`~sim_envs.scenes.episodes.Episode`, checked field by field)
    or ``"episode_index"`` (needs ``episodes=``), not both; other keys are refused naming the
    nearest valid one. ``step`` refuses a bad action (above) and, once a step returned
    ``terminated`` or ``truncated``, every call until ``reset``
    (:class:`~conceptfusion.errors.EnvStateError`). Constructor arguments are checked:
    ``backend`` a key of :data:`BACKENDS`; ``width``/``height`` and ``scan_width``/``scan_height``
    ints in [1, 8192] (the scan sizes may be ``None``); ``fovy_deg`` in (0, 180);
    ``max_steps`` an int >= 1; ``scan_frames`` an int >= 0; ``episodes`` an existing
    ``tabletop_rearrange`` episode file or a non-empty ``EpisodeSet``; ``scene`` ``None`` or a
    ``Scene``; ``scenes_root`` ``None`` or an existing folder.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 4}
    _renderer_attr = "sim"  # close() releases the simulation backend
    env_name = "TabletopRearrange"
    reset_option_keys = ("episode", "episode_index")

    def __init__(
        self,
        *,
        backend: str = "mujoco",
        episodes: str | EpisodeSet | None = None,
        scene: Scene | None = None,
        width: int = 320,
        height: int = 240,
        fovy_deg: float = 60.0,
        max_steps: int = 6,
        scenes_root: str | None = None,
        scan_frames: int = 0,
        scan_width: int | None = None,
        scan_height: int | None = None,
        segmentation: bool = True,
        render_mode: str | None = None,
    ) -> None:
        where = self.env_name
        _backend_entry(backend)  # raises naming the valid backends
        check_render_mode(render_mode)
        width, height = check_image_size(where, width, height)
        scan_width, scan_height = check_image_size(where, scan_width, scan_height, prefix="scan_", allow_none=True)
        fovy_deg = check_fovy(where, fovy_deg)
        scan_frames = check_int(where, "scan_frames", scan_frames, minimum=0)
        max_steps = check_int(where, "max_steps", max_steps, minimum=1)
        scenes_root = check_scenes_root(where, scenes_root)
        if scene is not None and not isinstance(scene, Scene):
            raise SimTypeError(f"{where}: scene: expected None or a Scene, got {type(scene).__name__}")
        if episodes is not None and not isinstance(episodes, (str, os.PathLike, EpisodeSet)):
            raise SimTypeError(f"{where}: episodes: expected None, an episode file path or an EpisodeSet, got {type(episodes).__name__}")
        episodes = check_episode_set(where, episodes, "tabletop_rearrange", scenes_root=scenes_root)
        self.backend, self.width, self.height, self.fovy_deg = backend, width, height, fovy_deg
        self.default_max_steps, self.render_mode = max_steps, render_mode
        self._episodes, self._fixed_scene, self._scenes_root = episodes, scene, scenes_root
        self.action_space = spaces.Box(ACTION_LOW, ACTION_HIGH, dtype=np.float32)
        self.observation_space = spaces.Dict(
            {
                **frame_spaces(height, width),
                "instruction": spaces.Text(_MAX_INSTRUCTION, min_length=1, charset=INSTRUCTION_CHARSET),
                "line": spaces.Box(-np.inf, np.inf, (2, 2), np.float64),
            }
        )
        self.segmentation = check_bool(where, "segmentation", segmentation)
        self.scan_frames = int(scan_frames)
        self.scan_width, self.scan_height = int(scan_width or width), int(scan_height or height)
        if self.scan_frames:
            n, sh, sw = self.scan_frames, self.scan_height, self.scan_width
            self.observation_space = spaces.Dict({
                **self.observation_space.spaces,
                "scan_rgb": spaces.Box(0, 255, (n, sh, sw, 3), np.uint8),
                "scan_depth": spaces.Box(0.0, np.inf, (n, sh, sw), np.float32),
                "scan_K": spaces.Box(-np.inf, np.inf, (n, 3, 3), np.float64),
                "scan_cam_to_world": spaces.Box(-np.inf, np.inf, (n, 4, 4), np.float64),
            })
        self.sim: TabletopSim | None = None
        self.episode: Episode | None = None
        self._start_poses = None
        self._object_phrases: list[list[str]] = []
        self._steps = 0
        self._last_frame: RGBDFrame | None = None
        self._last_push: dict = {}
        self._result: RearrangeResult | None = None

    # ----------------------------------------------------------------- episode set-up
    def _pick_episode(self, options: dict) -> tuple[Episode, Scene]:
        episodes = self._episodes.episodes if self._episodes is not None else None
        ep = episode_from_options(self.env_name, options, episodes, self.np_random)
        if ep is None:
            goals: tuple = ()
            while not goals:  # a generated scene with no object near the line is redrawn
                scene = self._fixed_scene or generate_tabletop(int(self.np_random.integers(0, 10_000)))
                goals = tabletop_goals(scene, self.np_random)
                if not goals and self._fixed_scene is not None:
                    raise SimError(f"{self.env_name}: scene {scene.id}: no object lies within {MAX_LINE_DISTANCE} m of the line to instruct")
            ep = Episode(f"random-{scene.id}", scene.id, scene.seed, tabletop_instruction(scene, goals), goals, None, self.default_max_steps)
            return ep, scene
        check_episode(self.env_name, ep, charset=INSTRUCTION_CHARSET, max_instruction=_MAX_INSTRUCTION, search=False)
        if self._fixed_scene is not None and ep.scene == self._fixed_scene.id:
            return ep, self._fixed_scene
        return ep, resolve_scene(ep.scene, ep.scene_seed, scenes_root=self._scenes_root)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        seed, options = self._begin_reset(seed, options)
        super().reset(seed=seed)
        ep, scene = self._pick_episode(options)
        for g in ep.goals:
            scene.object(g.object_id)  # KeyError naming the valid ids
        if self.sim is not None:
            self.sim.close()
        self.sim = make_backend(self.backend, scene, seed=int(self.np_random.integers(0, 2**31 - 1)))
        self.episode = ep
        self._start_poses = self.sim.object_poses()
        self._object_phrases = [answer_phrases(o) for o in scene.objects]
        self._steps = 0
        self._last_push = {}
        out = self._observe()
        self._episode_started()
        return out

    # ----------------------------------------------------------------- stepping
    def step(self, action):
        a = check_action(self.env_name, action, 5, "(start_x, start_y, direction_rad, distance, stop)")
        self._check_step()
        wrapped = (a[2] + np.pi) % (2 * np.pi) - np.pi
        clipped = np.clip(np.array([a[0], a[1], wrapped, a[3], a[4]]), ACTION_LOW, ACTION_HIGH).astype(np.float64)
        stop = bool(clipped[4] > 0.5)
        if stop:
            self._last_push = {"stop": True}
        else:
            out = self.sim.push(clipped[:2], float(clipped[2]), float(clipped[3]))
            self._last_push = {
                "stop": False, "executed": out.executed, "reason": out.reason, "contact": out.contact,
                "start_xy": clipped[:2].tolist(), "direction_rad": float(clipped[2]), "distance": float(clipped[3]),
                "clipped": bool(np.any(np.abs(clipped[[0, 1, 3]] - a[[0, 1, 3]]) > 1e-9)),
            }
        self._steps += 1
        terminated = stop
        truncated = not stop and self._steps >= self.episode.max_steps
        obs, info = self._observe()
        done = terminated or truncated
        reward = 1.0 if done and info["success"] else 0.0
        self._step_done(terminated, truncated)
        return obs, reward, terminated, truncated, info

    def evaluate(self) -> RearrangeResult:
        """Success judgement of the current state (see the class docstring)."""
        self._require_reset("evaluate()")
        return self._evaluate()

    def _evaluate(self) -> RearrangeResult:
        return evaluate(self.sim.scene, self._start_poses, self.sim.object_poses(), self.episode.goals)

    def _observe(self):
        scene = self.sim.scene
        eye, target = camera_pose(scene)
        f = self.sim.render(eye, target, self.width, self.height, self.fovy_deg, self.segmentation)
        self._last_frame = f
        self._result = self._evaluate()
        obs = {**f.observation(), "instruction": self.episode.instruction, "line": np.asarray(scene.line, np.float64)[:, :2].copy()}
        scan_seg = None
        if self.scan_frames:
            frames = self._scan(self.scan_frames, self.scan_width, self.scan_height, self.segmentation)
            obs["scan_rgb"] = np.stack([fr.rgb for fr in frames])
            obs["scan_depth"] = np.stack([fr.depth for fr in frames]).astype(np.float32)
            obs["scan_K"] = np.stack([fr.K for fr in frames]).astype(np.float64)
            obs["scan_cam_to_world"] = np.stack([fr.cam_to_world for fr in frames]).astype(np.float64)
            if self.segmentation:
                scan_seg = np.stack([fr.segmentation for fr in frames]).astype(np.int32)
        p0, n = line_normal(scene)
        half = np.asarray(scene.table.size[:2]) / 2
        info = {
            "episode_id": self.episode.episode_id,
            "scene_id": scene.id,
            **({"segmentation": f.segmentation} if self.segmentation else {}),
            **({"scan_segmentation": scan_seg} if scan_seg is not None else {}),
            "object_ids": [o.id for o in scene.objects],
            "object_names": [o.name for o in scene.objects],
            "object_phrases": [list(p) for p in self._object_phrases],
            "object_poses": self.sim.object_poses().tolist(),
            "object_aabbs": self.sim.object_aabbs().tolist(),
            "object_sizes": [list(o.size) for o in scene.objects],
            "target_ids": [g.object_id for g in self.episode.goals],
            "target_sides": [g.side for g in self.episode.goals],
            "line": [list(scene.line[0]), list(scene.line[1])],
            "right_normal": n,
            "view_dir": np.asarray(VIEW_DIR, np.float64),
            "table_xy": np.array([np.asarray(scene.table.center[:2]) - half, np.asarray(scene.table.center[:2]) + half]),
            "scene_graph": scene_graph(self.sim.mj) if hasattr(self.sim, "mj") else None,
            "last_push": dict(self._last_push),
            "evaluation": self._result.summary(),
            "success": self._result.success,
            "steps": self._steps,
        }
        return obs, info

    # ----------------------------------------------------------------- scans and rendering
    def scan(self, num_frames: int = 24, *, width: int | None = None, height: int | None = None, segmentation: bool = False) -> list[RGBDFrame]:
        """Posed RGB-D frames on an orbit around the table (radius 1.1 m, 0.75 m above the top,
        looking at its centre) in the current state; the episode does not advance.

        Frames follow the observation conventions (OpenCV, metric depth). ``segmentation=True``
        adds ground-truth instance masks, for scoring and privileged agents only.
        """
        self._require_reset("scan()")
        num_frames = check_int(self.env_name, "num_frames", num_frames, minimum=1)
        width, height = check_image_size(self.env_name, width, height, allow_none=True)
        return self._scan(num_frames, width or self.width, height or self.height, bool(segmentation))

    def _scan(self, num_frames: int, w: int, h: int, segmentation: bool) -> list[RGBDFrame]:
        return [self.sim.render(eye, tgt, w, h, self.fovy_deg, segmentation) for eye, tgt in orbit_trajectory(self.sim.scene, num_frames)]
