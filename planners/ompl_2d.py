"""Collision-free 2-D paths for a round mobile base on an inflated occupancy grid, with OMPL.

The base is round, so its heading does not matter for collisions: the state space is R^2 (x, y
in metres, world frame) bounded by the grid, and the robot is a point on a grid already inflated
by its radius (:meth:`planners.occupancy.OccupancyGrid.inflate`). A state is valid when its cell
is free; a motion is valid when every cell the straight segment passes through is free (exact
traversal, :mod:`planners.raycast`), so no thin wall is skipped between samples.

Order of checks in :func:`plan_base_path`, cheapest first: start cell, goal cell, connected
components of free space (an unreachable goal answers in milliseconds without calling OMPL),
the straight segment, then OMPL (RRT-Connect by default) with path simplification.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass

import numpy as np

from planners._checks import as_float_array, check_seed, positive_float
from planners._ompl_backend import PLANNERS, resolve_planner, solve
from planners.errors import PlannerTypeError
from planners.occupancy import OccupancyGrid, free_components
from planners.raycast import SegmentChecker
from planners.result import PlanResult

__all__ = ["BasePlannerConfig", "plan_base_path", "PLANNERS"]

_LOG = logging.getLogger(__name__)


@dataclass(frozen=True)
class BasePlannerConfig:
    """Options of :func:`plan_base_path`."""

    planner: str = "rrtconnect"
    """A key of :data:`PLANNERS` (``"rrtconnect"``, ``"rrtstar"``, ``"prm"``, ...)."""
    time_limit: float = 1.0
    """Seconds OMPL may search before the query answers ``"timeout"``."""
    simplify_time: float = 0.25
    """Upper bound in seconds on shortcutting the found path (the work is also bounded by a fixed
    number of rounds; paths repeat for a seed only when this bound is not reached); 0 keeps the
    raw planner path."""
    unknown_is_free: bool = True
    """Whether unobserved cells may be crossed (False: they block like obstacles)."""
    use_full_time: bool = False
    """Optimising planners keep improving until ``time_limit`` instead of stopping at the first path."""
    planner_range: float | None = None
    """Longest tree extension in metres for tree planners; None keeps OMPL's default."""

    def __post_init__(self) -> None:
        resolve_planner(self.planner)
        positive_float("time_limit", self.time_limit)
        positive_float("simplify_time", self.simplify_time, allow_zero=True)
        if self.planner_range is not None:
            positive_float("planner_range", self.planner_range)


def _cell_text(grid: OccupancyGrid, xy: np.ndarray) -> str:
    row, col = grid.world_to_cell(xy)
    return f"({xy[0]:.3f}, {xy[1]:.3f}) in cell (row {row}, col {col})"


def plan_base_path(
    grid: OccupancyGrid,
    start_xy,
    goal_xy,
    config: BasePlannerConfig | None = None,
    *,
    seed: int = 0,
) -> PlanResult:
    """Plan a collision-free path for a round base from ``start_xy`` to ``goal_xy``.

    ``grid`` must already be inflated by the robot radius. Never raises for a planning failure:
    blocked start or goal, an unreachable goal and a timeout come back as a
    :class:`PlanResult` status with a reason. Raises ``TypeError``/``ValueError`` for bad input
    (wrong shapes, NaN, unknown planner name).

    The same ``seed`` gives the same path as long as neither planning nor shortcutting reaches
    its time limit, the planner is single-threaded (not ``prm``/``prmstar``) and no other thread
    plans with OMPL at the same time (OMPL seeds from one process-wide generator).

    Shape:
        start_xy, goal_xy: (2,) world x, y in metres.
        returns: PlanResult with path (N, 2), N >= 2 when solved.
    """
    if not isinstance(grid, OccupancyGrid):
        raise PlannerTypeError(f"grid: expected an OccupancyGrid, got {type(grid).__name__}")
    config = BasePlannerConfig() if config is None else config
    if not isinstance(config, BasePlannerConfig):
        raise PlannerTypeError(f"config: expected a BasePlannerConfig, got {type(config).__name__}")
    start = as_float_array("start_xy", start_xy, (2,))
    goal = as_float_array("goal_xy", goal_xy, (2,))
    seed = check_seed(seed)
    planner = resolve_planner(config.planner)
    t0 = time.perf_counter()

    def result(status: str, reason: str, path=None, name: str = "") -> PlanResult:
        path = np.zeros((0, 2)) if path is None else path
        _LOG.debug("base plan %s: %s", status, reason)
        return PlanResult(status, reason, path, name, time.perf_counter() - t0, seed)  # type: ignore[arg-type]

    blocked = grid.blocked_hw(unknown_is_free=config.unknown_is_free)
    checker = SegmentChecker(blocked, grid.origin_xy, grid.resolution)
    inside = grid.in_bounds(np.stack([grid.world_to_cell(start), grid.world_to_cell(goal)]))
    if not inside[0]:
        return result("start_in_collision", f"start {_cell_text(grid, start)} lies outside the grid {grid.extent_xy}")
    if not checker.point_free(*start):
        return result("start_in_collision", f"start {_cell_text(grid, start)} is blocked in the inflated grid")
    if not inside[1]:
        return result("goal_in_collision", f"goal {_cell_text(grid, goal)} lies outside the grid {grid.extent_xy}")
    if not checker.point_free(*goal):
        return result("goal_in_collision", f"goal {_cell_text(grid, goal)} is blocked in the inflated grid")

    labels, _ = free_components(~blocked)
    (sr, sc), (gr, gc) = grid.world_to_cell(start), grid.world_to_cell(goal)
    if labels[sr, sc] != labels[gr, gc]:
        return result(
            "unreachable",
            f"goal {_cell_text(grid, goal)} is not connected to start {_cell_text(grid, start)} through free cells",
        )
    if checker.segment_free(*start, *goal):
        return result("solved", "the straight segment is free", np.stack([start, goal]), "straight")

    lower = grid.origin_xy.copy()
    # States must stay strictly inside the last cell: shave a tiny margin off the upper bound.
    upper = np.array(grid.extent_xy[2:]) - 1e-9 * grid.resolution
    outcome = solve(
        lower=lower,
        upper=upper,
        start=start,
        goal=goal,
        state_valid=lambda s: checker.point_free(s[0], s[1]),
        segment_valid=lambda a, b: checker.segment_free(a[0], a[1], b[0], b[1]),
        planner=planner,
        time_limit=config.time_limit,
        simplify_time=config.simplify_time,
        seed=seed,
        use_full_time=config.use_full_time,
        planner_range=config.planner_range,
    )
    if not outcome.solved:
        return result("timeout", outcome.reason + "; start and goal are connected, so a path exists", name=planner)
    return result("solved", outcome.reason, outcome.path, planner)

