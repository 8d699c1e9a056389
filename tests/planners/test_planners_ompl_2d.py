"""2-D base planning with OMPL on inflated grids: paths, typed failures, determinism."""

from __future__ import annotations

import re

import numpy as np
import pytest

from planners.errors import UnknownPlannerError
from planners.occupancy import GridConfig, OccupancyGrid, build_occupancy_grid
from planners.ompl_2d import BasePlannerConfig, plan_base_path
from planners.raycast import path_blocked_segments, segment_cells

RES = 0.05


def _border(h: int, w: int) -> np.ndarray:
    occ = np.zeros((h, w), dtype=bool)
    occ[0, :] = occ[-1, :] = occ[:, 0] = occ[:, -1] = True
    return occ


def _wall_grid() -> OccupancyGrid:
    """4 m x 3 m, border walls, a wall at x = 2 from y = 0 up to y = 2.4 (gap above it)."""
    occ = _border(60, 80)
    occ[:48, 40] = True
    return OccupancyGrid(np.zeros(2), RES, occ).inflate(0.2)


def _assert_path_free(grid: OccupancyGrid, path: np.ndarray) -> None:
    """Every cell every segment touches is in the grid and free; dense samples agree."""
    for a, b in zip(path[:-1], path[1:]):
        cells = segment_cells(grid, a, b)
        assert grid.in_bounds(cells).all()
        assert not grid.occupied_hw[cells[:, 0], cells[:, 1]].any(), f"segment {a} -> {b} hits an obstacle"
        t = np.linspace(0.0, 1.0, int(np.linalg.norm(b - a) / (RES / 10)) + 2)[:, None]
        assert not grid.is_blocked_xy(a + t * (b - a)).any()


def test_path_around_wall_is_collision_free():
    grid = _wall_grid()
    start, goal = np.array([1.0, 1.0]), np.array([3.0, 1.0])
    res = plan_base_path(grid, start, goal, seed=3)
    assert res.status == "solved", res.reason
    assert res.planner == "rrtconnect"
    np.testing.assert_allclose(res.path[0], start)
    np.testing.assert_allclose(res.path[-1], goal)
    assert res.path.shape[1] == 2 and len(res.path) >= 3  # the straight line is blocked
    _assert_path_free(grid, res.path)
    # The path must climb above the wall's inflated tip (2.4 m + 0.2 m) to get round it.
    assert res.path[:, 1].max() >= 2.6 - RES
    assert res.length >= 2 * np.hypot(1.0, 1.6) - 0.1


def test_path_in_room_built_from_point_cloud(room_cloud):
    grid = build_occupancy_grid(room_cloud, GridConfig(resolution=RES)).inflate(0.25)
    res = plan_base_path(grid, [1.0, 1.5], [3.0, 1.5], seed=0)
    assert res.status == "solved", res.reason
    _assert_path_free(grid, res.path)
    assert not path_blocked_segments(grid, res.path).any()


def test_straight_segment_skips_ompl():
    grid = _wall_grid()
    res = plan_base_path(grid, [0.5, 0.5], [1.5, 2.0])
    assert res.status == "solved" and res.planner == "straight"
    assert res.path.shape == (2, 2)


@pytest.mark.parametrize(
    ("start", "goal", "status", "match"),
    [
        ([2.0, 1.0], [3.0, 1.0], "start_in_collision", "start .* is blocked"),
        ([1.0, 1.0], [2.0, 0.5], "goal_in_collision", "goal .* is blocked"),
        ([-1.0, 1.0], [3.0, 1.0], "start_in_collision", "outside the grid"),
        ([1.0, 1.0], [3.0, 9.0], "goal_in_collision", "outside the grid"),
    ],
)
def test_blocked_start_or_goal(start, goal, status, match):
    res = plan_base_path(_wall_grid(), start, goal)
    assert res.status == status
    assert res.path.shape == (0, 2)
    assert re.search(match, res.reason), res.reason


def test_walled_off_goal_is_unreachable_without_ompl():
    occ = _border(60, 80)
    occ[10:30, 50] = occ[10:30, 70] = occ[10, 50:71] = occ[29, 50:71] = True  # closed closet
    grid = OccupancyGrid(np.zeros(2), RES, occ).inflate(0.1)
    res = plan_base_path(grid, [0.5, 0.5], [3.0, 1.0], seed=0)
    assert res.status == "unreachable"
    assert res.planner == ""  # answered by the component test, OMPL never ran
    assert "not connected" in res.reason


def test_diagonal_one_cell_wall_is_not_cut_through():
    occ = np.zeros((40, 40), dtype=bool)
    idx = np.arange(40)
    occ[idx, idx] = True  # cells touch only at corners
    grid = OccupancyGrid(np.zeros(2), RES, occ)
    res = plan_base_path(grid, [0.3, 1.5], [1.5, 0.3])
    assert res.status == "unreachable"


def test_same_seed_same_path():
    grid = _wall_grid()
    cfg = BasePlannerConfig(simplify_time=0.5)
    a = plan_base_path(grid, [1.0, 1.0], [3.0, 0.5], cfg, seed=11)
    b = plan_base_path(grid, [1.0, 1.0], [3.0, 0.5], cfg, seed=11)
    other = plan_base_path(grid, [1.0, 1.0], [3.0, 0.5], cfg, seed=12)
    assert a.solved and b.solved and other.solved
    np.testing.assert_array_equal(a.path, b.path)
    assert a.seed == 11 and other.seed == 12


def test_timeout_on_a_maze_with_a_tiny_time_limit():
    occ = _border(80, 80)
    for k, col in enumerate(range(16, 72, 16)):
        if k % 2 == 0:
            occ[:74, col] = True
        else:
            occ[6:, col] = True
    grid = OccupancyGrid(np.zeros(2), RES, occ)
    res = plan_base_path(grid, [0.2, 0.2], [3.8, 0.2], BasePlannerConfig(time_limit=1e-5), seed=0)
    assert res.status == "timeout"
    assert "connected" in res.reason
    solved = plan_base_path(grid, [0.2, 0.2], [3.8, 0.2], BasePlannerConfig(time_limit=5.0), seed=0)
    assert solved.status == "solved"
    _assert_path_free(grid, solved.path)


@pytest.mark.parametrize("name", ["rrtstar", "prm", "RRT*", "rrt"])
def test_other_planners_by_name(name):
    grid = _wall_grid()
    res = plan_base_path(grid, [1.0, 1.0], [3.0, 1.0], BasePlannerConfig(planner=name), seed=1)
    assert res.status == "solved", res.reason
    _assert_path_free(grid, res.path)


def test_unknown_cells_block_when_asked():
    occ = _border(20, 40)
    known = np.ones_like(occ)
    known[:, 20] = False  # an unobserved strip across the corridor
    grid = OccupancyGrid(np.zeros(2), RES, occ, known)
    free = plan_base_path(grid, [0.3, 0.5], [1.7, 0.5])
    blocked = plan_base_path(grid, [0.3, 0.5], [1.7, 0.5], BasePlannerConfig(unknown_is_free=False))
    assert free.status == "solved" and blocked.status == "unreachable"


def test_bad_input_raises():
    grid = _wall_grid()
    with pytest.raises(UnknownPlannerError, match="did you mean 'rrtconnect'"):
        BasePlannerConfig(planner="rrtconect")
    with pytest.raises(ValueError, match="finite"):
        plan_base_path(grid, [np.nan, 1.0], [3.0, 1.0])
    with pytest.raises(ValueError, match=r"expected shape \(2,\)"):
        plan_base_path(grid, [1.0, 1.0, 0.0], [3.0, 1.0])
    with pytest.raises(TypeError, match="OccupancyGrid"):
        plan_base_path(np.zeros((3, 3), bool), [1.0, 1.0], [3.0, 1.0])
    with pytest.raises(ValueError, match="seed"):
        plan_base_path(grid, [1.0, 1.0], [3.0, 1.0], seed=-1)
    with pytest.raises(ValueError, match="time_limit"):
        BasePlannerConfig(time_limit=0.0)
