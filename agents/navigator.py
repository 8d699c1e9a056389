"""The waypoint navigator (paper: "drive to the football field"): map, query, plan, follow, stop.

Per step the navigator fuses the current RGB-D frame into its ConceptFusion map, then acts by
phase:

1. ``look``: turn in place through a full circle, mapping the surroundings;
2. ``plan``: query the map for the goal description. Found: build a 2-D occupancy grid from the
   map's points (obstacle height band), inflate it by the robot radius, pick a reachable goal
   cell within ``standoff`` of the region's footprint and plan to it with OMPL. Not found: plan
   to the best frontier (explored free space next to unobserved space) instead;
3. ``follow``: pure-pursuit tracking of the path, re-querying the goal and checking the path
   against the updated grid every few steps (replan when blocked or when the goal appears);
4. at the goal: ``stop``. With no goal and no frontier left, it stops where it is (with
   ``presume_after``, it first presumes the goal present and heads for its best guess).

In a multi-goal search (the observation's ``goal`` changes after a stop) it keeps its map and
plans for the new goal at once: what it saw while looking for the earlier goals answers the
query, and only the goal's own state (sightings, presumption, its step count) starts again. With
``look_again`` (the map-free twin) it looks around first and explores again what it saw before.
An exploration phase before the first goal (the goal reads
:data:`~conceptfusion.tasks.EXPLORE_GOAL`, "explore, then fetch") is frontier exploration with
no query; the first real goal then counts as the next goal.

Observations: ``rgb``, ``depth``, ``K``, ``cam_to_world`` (posed RGB-D), ``base_pose`` (x, y,
yaw odometry) and ``goal`` (text). Actions: ``[linear m/s, angular rad/s, stop]`` (stop > 0.5
ends the episode), the ``cf/ObjectSearch`` action space.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from scipy import ndimage

from agents.concept_map import ConceptMapper, privileged_labels
from agents.frontier import choose_frontier, find_frontiers
from conceptfusion.cameras import world_points
from conceptfusion.map.query import QueryResult
from conceptfusion.tasks import EXPLORE_GOAL
from planners.occupancy import GridConfig, build_occupancy_grid, nearest_free_cell, reachable_goal_near
from planners.ompl_2d import BasePlannerConfig, plan_base_path
from planners.replan import check_path_blocked
from planners.tracking import PurePursuitConfig, TrackingState, pure_pursuit_step

__all__ = ["NavigatorConfig", "MapNavigator", "search_action"]

_LOG = logging.getLogger(__name__)


def search_action(linear: float = 0.0, angular: float = 0.0, stop: bool = False) -> np.ndarray:
    """An ObjectSearch action: ``[linear, angular, stop]`` as float32, shape (3,)."""
    return np.array([linear, angular, 1.0 if stop else 0.0], np.float32)


@dataclass(frozen=True)
class NavigatorConfig:
    """Settings of :class:`MapNavigator`."""

    robot_radius: float = 0.25
    """Base radius (m); the grid is inflated by this plus ``clearance``."""
    clearance: float = 0.05
    """Extra margin (m) kept from obstacles."""
    standoff: float = 0.9
    """Goal cells lie within this distance (m) of the object's footprint (success is 1.0 m)."""
    grid: GridConfig = field(default_factory=lambda: GridConfig(resolution=0.05, obstacle_z_min=0.08, obstacle_z_max=1.6, padding=1.0))
    tracking: PurePursuitConfig = field(default_factory=lambda: PurePursuitConfig(lookahead=0.35, max_linear=0.5, max_angular=1.2, goal_tolerance=0.12))
    planner: BasePlannerConfig = field(default_factory=lambda: BasePlannerConfig(time_limit=0.5))
    look_angular: float = 1.2
    """Yaw rate (rad/s) of the look-around turn."""
    goal_tolerance: float = 0.05
    """Distance (m) to the end of a path to the goal at which the base counts as arrived (paths to
    frontiers use ``tracking.goal_tolerance``). A goal cell lies within ``standoff`` of the
    object (or as close as free space allows); arriving a whole tracking tolerance short of it
    could leave the base outside the 1.0 m that counts as success."""
    recheck_every: int = 4
    """Steps between goal re-queries and path checks while following."""
    max_plan_failures: int = 6
    """Stop after this many consecutive planning failures."""
    integrate_every: int = 1
    """Fuse every k-th frame while driving (every frame while looking around); > 1 trades map
    density for speed with slow encoders."""
    keyframe_move: float = 0.3
    """Fuse a frame only when the base has moved at least this far (m) or turned at least
    ``keyframe_turn_deg`` since the last fused frame (the first frame always); 0 and 0: every
    frame (as ``integrate_every`` says). Frames from nearly the same viewpoint add little to the
    map but cost a full perception pass. With the defaults the look-around turn (34 degrees a
    step) fuses every other frame, 69 degrees apart, inside the camera's 86-degree horizontal
    field of view. The defaults (0.3 m, 40 degrees) were chosen on development episodes for more
    successes at half the time a step; see docs/measurement-history.md."""
    keyframe_turn_deg: float = 40.0
    """The turn (degrees) that makes a frame a keyframe (see ``keyframe_move``)."""
    presume_after: int = 200
    """From this step on (0: never), and once no frontier is left, a goal the score floor rejects
    everywhere is presumed present, as an instruction's objects are for the pushers: the search
    heads for its best region under the floor (it must still beat the generic phrases) or, failing
    that, the region that scores highest for its name alone
    (:meth:`~agents.concept_map.ConceptMapper.locate_present`). A search that would run out its
    steps, or stop with nothing left to explore, ends at a guess instead. A privileged mapper
    (ground-truth perception) never presumes: a goal it does not find has not been seen yet, and
    its search goes on. Chosen on development episodes, where it gained searches of unseen
    objects and lost none; see docs/measurement-history.md."""

    hold_sighting: bool = False
    """Keep heading for the goal's last sighting (its footprint when an answer last found it)
    while the current answer does not find it. The map-free twin's one memory of a detection, as
    a detector-plus-planner searcher keeps its target once localised: its answers come from the
    current frame only (``MapperConfig.semantic_views=1``), so without it the goal would be
    forgotten as soon as it leaves the view. Off for the map navigator, whose map remembers."""

    look_again: bool = False
    """In a multi-goal search, space seen before the current goal was revealed counts as unexplored
    for frontiers again (the occupancy grid and the planner keep all of it). The map-free twin's
    setting: it remembers where it has been but not what it saw there, so a later goal sends it
    to look again rather than presume. Off for the map navigator, whose map remembers what it saw."""

    def __post_init__(self) -> None:
        if not (isinstance(self.goal_tolerance, (int, float)) and not isinstance(self.goal_tolerance, bool)
                and 0 < self.goal_tolerance < math.inf):
            raise ValueError(f"goal_tolerance: expected a finite number > 0, got {self.goal_tolerance!r}")
        value = self.presume_after
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            raise ValueError(f"presume_after: expected an integer >= 0, got {value!r}")
        for name in ("hold_sighting", "look_again"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"{name}: expected a bool, got {getattr(self, name)!r}")
        for name in ("keyframe_move", "keyframe_turn_deg"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and not isinstance(value, bool) and 0 <= value < math.inf):
                raise ValueError(f"{name}: expected a finite number >= 0, got {value!r}")


_CLOSE_STRIDE = 2
"""Pixel stride of the depth samples that mark space seen since a later goal was revealed
(``look_again``)."""

_CLOSE_FILL = 2
"""Closing iterations that fill the gaps between those samples on the grid."""


class MapNavigator:
    """Map-equipped object-search agent (see the module docstring).

    Args:
        mapper: the ConceptFusion mapper (perceived or oracle).
        config: see :class:`NavigatorConfig`.
        seed: seeds OMPL.
    """

    def __init__(self, mapper: ConceptMapper, config: NavigatorConfig = NavigatorConfig(), *, seed: int = 0) -> None:
        self.mapper, self.config, self.seed = mapper, config, int(seed)
        self.locator: Callable[[str, bool], QueryResult] | None = None
        """Answers the goal in place of ``mapper.locate`` when set: ``locator(goal, presume)``,
        ``presume`` True once ``presume_after`` applies (the instruction agents resolve an
        instruction through their planner, :mod:`agents.instruct.agent`)."""
        self._goal_tracking = dataclasses.replace(config.tracking, goal_tolerance=config.goal_tolerance)
        """The tracker's settings on paths to the goal (frontier paths use ``config.tracking``)."""
        self.privileged = mapper.privileged
        self.reset()

    def reset(self, *, seed: int | None = None) -> None:
        if seed is not None:
            self.seed = int(seed)
        self._started = False
        self._phase = "look"
        self._turned = 0.0
        self._last_yaw: float | None = None
        self._path: np.ndarray | None = None
        self._track = TrackingState()
        self._to_goal = False
        self._steps = 0
        self._failures = 0
        self._visited: list[np.ndarray] = []
        self._closest_approach: float | None = None
        self._seen: np.ndarray | None = None
        """Footprint (m, 2) of the goal when the map last found it."""
        self._last_fused: np.ndarray | None = None
        self._presumed: str | None = None
        """How the goal was last presumed present (``presume_after``), None before."""
        self._exhausted = False
        """No frontier was left (``presume_after``: the goal is presumed present from then on)."""
        self._presumes = bool(self.config.presume_after) and not self.privileged
        self._goal_start = 0
        """The step at which the current goal was revealed (``presume_after`` counts from it)."""
        """Whether this search may presume its goal present (``presume_after``, perceived maps only)."""
        self._close_keys = np.zeros(0, np.int64)
        """Space seen since the current goal of a chain was revealed (``look_again``): world
        (x, y) on a lattice of half the grid's cell side, as ``ix * 2**32 + iy`` keys, sorted and
        unique."""
        self._looking_again = False
        """A later goal of a chain is being searched with ``look_again``: frontiers count only the
        space seen since it was revealed."""
        self.log: list[str] = []
        """Why the agent did what it did, one line per decision (for reports)."""
        self.gave_up = False
        """The last ``stop`` came with no goal found and nothing left to explore (or after
        repeated planning failures): a caller with other goals to try may go on instead."""

    # -- helpers ---------------------------------------------------------------------------

    def _note(self, text: str) -> None:
        self.log.append(f"step {self._steps}: {text}")
        _LOG.debug(text)

    def _grids(self, position_xy=None):
        """Raw and inflated occupancy grids from the map's points. When the base's own cell is
        blocked after inflation (it stands closer to a wall than radius + clearance, or the
        wall's points are spread by noise), the inflation falls back to the bare radius and, if
        still blocked, the cells under the base are cleared so it can plan its way out."""
        pts = self.mapper.map.points
        grid = build_occupancy_grid(pts, self.config.grid)
        c = self.config
        inflated = grid.inflate(c.robot_radius + c.clearance + grid.resolution / 2)
        if position_xy is None or not inflated.is_blocked_xy(np.asarray(position_xy)[None])[0]:
            return grid, inflated
        inflated = grid.inflate(c.robot_radius)
        if inflated.is_blocked_xy(np.asarray(position_xy)[None])[0]:
            centres = inflated.cell_to_world(np.argwhere(np.ones(inflated.shape, bool))).reshape(*inflated.shape, 2)
            near = np.linalg.norm(centres - np.asarray(position_xy), axis=-1) <= max(c.robot_radius / 2, grid.resolution)
            inflated = dataclasses.replace(inflated, occupied_hw=inflated.occupied_hw & ~near)
        return grid, inflated

    def _see_close(self, observation) -> None:
        """Add the space this frame shows within the map's depth range to the set seen since
        the current goal was revealed (``look_again``)."""
        xy = world_points(observation["depth"], observation["K"], observation["cam_to_world"],
                          max_depth=self.mapper.config.max_depth, stride=_CLOSE_STRIDE)[:, :2]
        step = self.config.grid.resolution / 2
        ij = np.floor(xy / step).astype(np.int64)
        keys = (ij[:, 0] << 32) + (ij[:, 1] & 0xFFFFFFFF)
        self._close_keys = np.union1d(self._close_keys, keys)

    def _frontier_grid(self, grid):
        """The grid frontiers are found on: ``grid`` itself, or while looking again
        (``look_again``) its observed cells narrowed to those seen since the current goal was
        revealed (occupied cells stay observed)."""
        if not self._looking_again:
            return grid
        close = np.zeros(grid.shape, bool)
        if len(self._close_keys):
            ix = self._close_keys >> 32
            iy = (self._close_keys & 0xFFFFFFFF).astype(np.int64)
            iy = np.where(iy >= 2**31, iy - 2**32, iy)
            step = self.config.grid.resolution / 2
            cells = grid.world_to_cell((np.stack([ix, iy], axis=1) + 0.5) * step)
            cells = cells[grid.in_bounds(cells)]
            close[cells[:, 0], cells[:, 1]] = True
            # Depth samples land sparsely on far, slanted floor: close gaps of a few cells.
            close = ndimage.binary_closing(close, iterations=_CLOSE_FILL)
        return dataclasses.replace(grid, known_hw=(grid.known_hw & close) | grid.occupied_hw)

    def _locate(self):
        """The map's answer for the goal (presumed present once ``presume_after`` applies).
        While exploring (the goal reads :data:`~conceptfusion.tasks.EXPLORE_GOAL`) nothing is
        asked: nothing is found."""
        c = self.config
        if self._goal == EXPLORE_GOAL:
            return QueryResult(False, [], np.zeros(0, np.float32), np.zeros(0, np.float32), np.zeros(0, np.float32),
                               reason="exploring: no goal yet")
        presume = self._presumes and (self._steps - self._goal_start >= c.presume_after or self._exhausted)
        if self.locator is not None:
            return self.locator(self._goal, presume)
        if presume:
            found = self.mapper.locate_present(self._goal)
            presumed = found.extras.get("presumed")
            if presumed and presumed != self._presumed:
                self._presumed = presumed
                self._note(f"'{self._goal}' presumed present ({presumed}): {found.extras['passed_over'][0]}")
        else:
            found = self.mapper.locate(self._goal)
        return found

    def _within_reach(self, footprint: np.ndarray, start: np.ndarray) -> float | None:
        """Distance (m) from ``start`` to the footprint when close enough to stop, else None."""
        near = float(np.min(np.linalg.norm(footprint - start, axis=1)))
        if near <= self.config.standoff + 0.05 or (self._closest_approach and near <= self._closest_approach + 0.05):
            return near
        return None

    def _plan(self, pose: np.ndarray, *, arrived: bool = False) -> np.ndarray:
        """Choose a target (goal or frontier), plan to it; returns the next action. ``arrived``:
        the base has just reached the end of a path to the goal."""
        goal_text = self._goal
        found = self._locate()
        start = pose[:2]
        if not found.found and arrived and self._seen is not None:
            # Frames from close by can drop the goal's score under the floor just as the base
            # arrives: it was seen here, so stop rather than wander off.
            near = self._within_reach(self._seen, start)
            if near is not None:
                self._note(f"'{goal_text}' no longer stands out, but it was seen {near:.2f} m from here: stop")
                return search_action(stop=True)
        grid, inflated = self._grids(start)
        target, self._to_goal = None, False
        held = not found.found and self.config.hold_sighting and self._seen is not None
        if found.found or held:
            footprint = self._seen = found.best.points_n3[:, :2] if found.found else self._seen
            if held:
                self._note(f"'{goal_text}' not in view; heading for where it was last seen")
            near = self._within_reach(footprint, start)
            if near is not None:
                self._note(f"'{goal_text}' is within reach ({near:.2f} m): stop")
                return search_action(stop=True)
            target = reachable_goal_near(inflated, start, footprint, standoff=self.config.standoff)
            if target is None:
                # Deep inside furniture or behind clutter: get as close as the free space allows.
                target = nearest_free_cell(inflated, np.median(footprint, axis=0), reachable_from_xy=start)
                if target is not None:
                    self._closest_approach = float(np.min(np.linalg.norm(footprint - target, axis=1)))
                    self._note(f"'{goal_text}' found; no free cell within {self.config.standoff} m, approaching to {self._closest_approach:.2f} m")
            if target is not None:
                self._to_goal = True
            else:
                self._note(f"'{goal_text}' found but not reachable from here; exploring")
        if target is None:
            frontier = choose_frontier(find_frontiers(self._frontier_grid(grid), start, inflated=inflated), start, self._visited)
            if frontier is None:
                if self._goal == EXPLORE_GOAL:
                    self._note("exploring: no frontier left, looking around until a goal is given")
                    self._phase, self._turned = "look", 0.0
                    return search_action(0.0, self.config.look_angular)
                if self._presumes and not self._exhausted:
                    self._exhausted = True
                    self._note("no goal and no frontier left: presuming the goal present")
                    return self._plan(pose)
                self._note("no goal and no frontier left: stop")
                self.gave_up = True
                return search_action(stop=True)
            target = frontier.target_xy
            self._visited.append(target)
        plan = plan_base_path(inflated, start, target, self.config.planner, seed=self.seed + self._steps)
        if not plan.solved:
            self._failures += 1
            self._note(f"planning to {np.round(target, 2).tolist()} failed: {plan.status} ({plan.reason})")
            if self._failures >= self.config.max_plan_failures:
                self.gave_up = True
                return search_action(stop=True)
            if plan.status == "start_in_collision":  # wedged against something: back off
                return search_action(-0.2, 0.0)
            self._phase = "look"
            self._turned = 0.0
            return search_action(0.0, self.config.look_angular)
        self._failures = 0
        if self._to_goal and plan.length <= 2 * self.config.goal_tolerance:
            self._note(f"at the closest free point to '{goal_text}': stop")
            return search_action(stop=True)
        self._path, self._track, self._phase = plan.path, TrackingState(), "follow"
        self._note(f"{'goal' if self._to_goal else 'frontier'} path of {plan.length:.2f} m to {np.round(target, 2).tolist()}")
        return self._follow(pose)

    def _follow(self, pose: np.ndarray) -> np.ndarray:
        tracking = self._goal_tracking if self._to_goal else self.config.tracking
        cmd, self._track = pure_pursuit_step(pose, self._path, self._track, tracking)
        if cmd.done:
            if self._to_goal:
                return self._plan(pose, arrived=True)  # re-check from here: stops when within reach
            self._phase, self._turned = "look", 0.0
            return search_action(0.0, self.config.look_angular)
        return search_action(cmd.linear, cmd.angular)

    def _fuse_now(self, pose: np.ndarray) -> bool:
        """Whether this step's frame goes into the map (``integrate_every``, then the keyframe rule)."""
        c = self.config
        if not (self._phase == "look" or self._steps % max(1, c.integrate_every) == 0):
            return False
        if self._last_fused is None or (c.keyframe_move <= 0 and c.keyframe_turn_deg <= 0):
            return True
        moved = float(np.hypot(*(pose[:2] - self._last_fused[:2])))
        turned = abs(math.degrees(math.remainder(pose[2] - self._last_fused[2], 2 * math.pi)))
        return (c.keyframe_move > 0 and moved >= c.keyframe_move) or (c.keyframe_turn_deg > 0 and turned >= c.keyframe_turn_deg)

    def _next_goal(self, goal: str) -> None:
        """A multi-goal search revealed its next goal: keep the map and everything explored, start
        the goal's own state again and plan for it on this step."""
        self._note(f"next goal '{goal}' (after '{self._goal}')")
        self._goal, self._goal_start = goal, self._steps
        self._seen = self._closest_approach = self._presumed = None
        self._exhausted, self._failures = False, 0
        self._path, self._to_goal, self._phase = None, False, "plan"
        if self.config.look_again:  # nothing counts as explored: look around from here first
            self._looking_again, self._close_keys, self._visited = True, np.zeros(0, np.int64), []
            self._phase, self._turned, self._last_fused = "look", 0.0, None

    # -- protocol --------------------------------------------------------------------------

    def act(self, observation, info: dict | None = None) -> np.ndarray:
        pose = np.asarray(observation["base_pose"], np.float64)
        if not self._started:
            self._goal = str(observation["goal"])
            self.mapper.reset(**privileged_labels(self.mapper, info))
            self._started = True
        elif str(observation["goal"]) != self._goal:
            self._next_goal(str(observation["goal"]))
        if self._fuse_now(pose):
            self.mapper.integrate(observation, segmentation=(info or {}).get("segmentation") if self.privileged else None)
            self._last_fused = pose.copy()
            if self._looking_again:
                self._see_close(observation)
        self._steps += 1
        if self._last_yaw is not None:
            self._turned += abs(math.remainder(pose[2] - self._last_yaw, 2 * math.pi))
        self._last_yaw = float(pose[2])
        if self._phase == "look":
            if self._turned < 2 * math.pi - 0.3:
                return search_action(0.0, self.config.look_angular)
            return self._plan(pose)
        if self._phase == "follow":
            if self._steps % self.config.recheck_every == 0:
                if not self._to_goal and self._locate().found:
                    self._note(f"'{self._goal}' appeared: replan")
                    return self._plan(pose)
                _, inflated = self._grids(pose[:2])
                if check_path_blocked(inflated, self._path, position_xy=pose[:2], skip_distance=0.3).blocked:
                    self._note("path blocked: replan")
                    return self._plan(pose)
            return self._follow(pose)
        return self._plan(pose)
