"""Map-free baselines, with the same interfaces as the map-equipped agents.

* :class:`RandomPusher` / :class:`RandomWalker`: random actions (tabletop pushes / base motion),
  stopping at a random time;
* :class:`FrameSearcher`: object search that checks every frame with the same perception as the
  map-equipped navigator but keeps no map: it drives towards the goal while the current frame
  shows it, and otherwise wanders reactively (forward while the frame shows free space ahead,
  turning away from obstacles, looking around now and then);
* the single-frame (2.5D) pusher is :class:`agents.pusher.MapPusher` with a non-persistent mapper
  and no scan (see :mod:`agents.builtin`).
"""

from __future__ import annotations

import math

import numpy as np

from agents.concept_map import ConceptMapper, privileged_labels
from agents.navigator import search_action
from agents.pusher import push_action
from conceptfusion.cameras import world_points
from conceptfusion.tasks import EXPLORE_GOAL

__all__ = ["RandomPusher", "RandomWalker", "FrameSearcher"]


class RandomPusher:
    """Random straight pushes on the table top; stops after a random number of pushes."""

    privileged = False
    reads_scan = False

    def __init__(self, *, table_half_xy: tuple[float, float] = (0.55, 0.35), max_pushes: int = 4, seed: int = 0) -> None:
        self.half = np.asarray(table_half_xy, np.float64)
        self.max_pushes, self.seed = int(max_pushes), int(seed)
        self.reset()

    def reset(self, *, seed: int | None = None) -> None:
        self.rng = np.random.default_rng(self.seed if seed is None else seed)
        self._left = int(self.rng.integers(1, self.max_pushes, endpoint=True))  # max_pushes up to 2**63 - 1

    def act(self, observation, info=None) -> np.ndarray:
        if self._left <= 0:
            return push_action((0.0, 0.0), 0.0, 0.0, stop=True)
        self._left -= 1
        xy = self.rng.uniform(-self.half, self.half)
        return push_action(xy, float(self.rng.uniform(-math.pi, math.pi)), float(self.rng.uniform(0.05, 0.4)))


class RandomWalker:
    """Random velocity commands held for a few steps; stops with probability ``p_stop`` per step."""

    privileged = False
    reads_images = False  # blind: it never looks at the observation

    def __init__(self, *, p_stop: float = 0.01, hold_steps: int = 4, seed: int = 0) -> None:
        self.p_stop, self.hold, self.seed = float(p_stop), int(hold_steps), int(seed)
        self.reset()

    def reset(self, *, seed: int | None = None) -> None:
        self.rng = np.random.default_rng(self.seed if seed is None else seed)
        self._cmd, self._left = (0.0, 0.0), 0

    def act(self, observation, info=None) -> np.ndarray:
        if self.rng.random() < self.p_stop:
            return search_action(stop=True)
        if self._left <= 0:
            self._cmd = (float(self.rng.uniform(0.0, 0.5)), float(self.rng.uniform(-1.2, 1.2)))
            self._left = self.hold
        self._left -= 1
        return search_action(*self._cmd)


class FrameSearcher:
    """Object search from the current frame only (no map); see the module docstring.

    Args:
        mapper: a mapper with ``MapperConfig(persistent=False)`` (each frame replaces the map).
        standoff: stop when the goal's nearest point is this close (m, horizontally).
        robot_radius: half-width of the corridor checked for obstacles ahead.
        look_every: steps between full look-around turns while wandering.
    """

    def __init__(self, mapper: ConceptMapper, *, standoff: float = 0.7, robot_radius: float = 0.25, look_every: int = 25) -> None:
        if mapper.config.persistent:
            raise ValueError("FrameSearcher: expected a non-persistent mapper (MapperConfig(persistent=False))")
        self.mapper, self.standoff, self.radius, self.look_every = mapper, float(standoff), float(robot_radius), int(look_every)
        self.privileged = mapper.privileged
        self.reset()

    def reset(self, *, seed: int | None = None) -> None:
        self._started = False
        self._steps = 0
        self._turn_left = 0
        self._turn_sign = 1.0

    def _obstacles(self, observation) -> np.ndarray:
        pts = world_points(observation["depth"], observation["K"], observation["cam_to_world"], max_depth=4.0)
        return pts[(pts[:, 2] > 0.08) & (pts[:, 2] < 1.6)]

    def _clear_ahead(self, pose, obstacles, length: float = 0.6) -> bool:
        d = np.array([math.cos(pose[2]), math.sin(pose[2])])
        rel = obstacles[:, :2] - pose[:2]
        along, across = rel @ d, np.abs(rel @ np.array([-d[1], d[0]]))
        return not np.any((along > 0) & (along < length + self.radius) & (across < self.radius + 0.05))

    def act(self, observation, info: dict | None = None) -> np.ndarray:
        pose = np.asarray(observation["base_pose"], np.float64)
        if not self._started:
            self.mapper.reset(**privileged_labels(self.mapper, info))
            self._started = True
        self._goal = str(observation["goal"])  # a multi-goal search reveals its goals one at a time
        self.mapper.integrate(observation, segmentation=(info or {}).get("segmentation") if self.privileged else None)
        self._steps += 1
        obstacles = self._obstacles(observation)
        res = self.mapper.locate(self._goal) if self._goal != EXPLORE_GOAL else None
        if res is not None and res.found:
            pts = res.best.points_n3[:, :2]
            if np.min(np.linalg.norm(pts - pose[:2], axis=1)) <= self.standoff:
                return search_action(stop=True)
            target = res.best.median[:2]
            err = math.remainder(math.atan2(target[1] - pose[1], target[0] - pose[0]) - pose[2], 2 * math.pi)
            if abs(err) > 0.35:
                return search_action(0.0, float(np.clip(2.0 * err, -1.2, 1.2)))
            if self._clear_ahead(pose, obstacles, 0.4):
                return search_action(0.4, float(np.clip(1.5 * err, -1.2, 1.2)))
            return search_action(0.0, 1.0 if err >= 0 else -1.0)
        if self._turn_left > 0:  # finishing a look-around or an avoidance turn
            self._turn_left -= 1
            return search_action(0.0, 1.2 * self._turn_sign)
        if self._steps % self.look_every == 0:
            self._turn_left = int(math.ceil(2 * math.pi / (1.2 * 0.5))) - 1
            return search_action(0.0, 1.2 * self._turn_sign)
        if self._clear_ahead(pose, obstacles):
            return search_action(0.45, 0.0)
        # Blocked: turn towards the side with fewer obstacles, for a random-ish while.
        d = np.array([math.cos(pose[2]), math.sin(pose[2])])
        rel = obstacles[:, :2] - pose[:2]
        left = np.sum(rel @ np.array([-d[1], d[0]]) > 0)
        self._turn_sign = -1.0 if left > len(rel) - left else 1.0
        self._turn_left = 2 + self._steps % 3
        return search_action(0.0, 1.2 * self._turn_sign)
