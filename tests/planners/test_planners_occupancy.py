"""Occupancy grid: rasterisation of a room cloud, conversions, inflation, reachability, goals."""

from __future__ import annotations

import numpy as np
import pytest

from planners.errors import PlannerError
from planners.occupancy import (
    GridConfig,
    OccupancyGrid,
    build_occupancy_grid,
    free_components,
    nearest_free_cell,
    reachable_goal_near,
)


def _occupied_at(grid: OccupancyGrid, x: float, y: float) -> bool:
    row, col = grid.world_to_cell([x, y])
    return bool(grid.occupied_hw[row, col])


def test_room_cloud_marks_walls_and_box(room_cloud):
    grid = build_occupancy_grid(room_cloud, GridConfig(resolution=0.05, obstacle_z_min=0.1, obstacle_z_max=1.5))
    # Points span [0, 4] x [0, 3]: floor(4 / 0.05) + 1 = 81 columns, 61 rows.
    assert grid.shape == (61, 81)
    np.testing.assert_allclose(grid.origin_xy, [0.0, 0.0])
    assert _occupied_at(grid, 0.01, 1.5) and _occupied_at(grid, 4.0, 1.5)  # side walls
    assert _occupied_at(grid, 2.0, 0.0) and _occupied_at(grid, 2.0, 3.0)
    assert _occupied_at(grid, 2.0, 1.5)  # box centre
    assert _occupied_at(grid, 1.72, 1.22)  # box corner region
    assert not _occupied_at(grid, 1.0, 1.0)  # open floor
    assert not _occupied_at(grid, 3.0, 2.0)  # lamp above the robot's height
    assert not _occupied_at(grid, 1.0, 2.5)  # clutter below the obstacle band
    assert grid.known_hw.all()  # the floor was sampled everywhere
    # Box points span x in [1.7125, 2.2875] -> columns 34..45, y in [1.2125, 1.7875] -> rows 24..35.
    rows, cols = np.nonzero(grid.occupied_hw[2:-2, 2:-2])
    assert (rows.min() + 2, rows.max() + 2, cols.min() + 2, cols.max() + 2) == (24, 35, 34, 45)


def test_unknown_cells_and_bounds():
    pts = np.array([[0.05, 0.05, 0.0], [0.25, 0.05, 0.5], [0.95, 0.95, 0.3]])
    grid = build_occupancy_grid(pts, GridConfig(resolution=0.1), bounds_xy=(0.0, 0.0, 1.0, 1.0))
    assert grid.shape == (10, 10)
    assert grid.known_hw.sum() == 3  # one floor cell, two occupied cells
    assert grid.occupied_hw[0, 2] and grid.occupied_hw[9, 9]
    blocked = grid.blocked_hw(unknown_is_free=False)
    assert blocked.sum() == 99  # everything but the single floor cell
    assert grid.blocked_hw(unknown_is_free=True).sum() == 2


def test_min_points_filters_noise():
    pts = np.array([[0.05, 0.05, 0.5], [0.15, 0.05, 0.5], [0.16, 0.06, 0.5]])
    grid = build_occupancy_grid(pts, GridConfig(resolution=0.1, min_points=2), bounds_xy=(0, 0, 0.3, 0.1))
    assert grid.occupied_hw.tolist() == [[False, True, False]]


def test_world_cell_round_trip_golden():
    grid = OccupancyGrid(np.array([-1.0, -2.0]), 0.5, np.zeros((4, 5), dtype=bool))
    assert grid.world_to_cell([0.2, -1.1]).tolist() == [1, 2]
    np.testing.assert_allclose(grid.cell_to_world([1, 2]), [0.25, -1.25])
    cells = np.array([[0, 0], [3, 4]])
    np.testing.assert_array_equal(grid.world_to_cell(grid.cell_to_world(cells)), cells)
    assert grid.extent_xy == (-1.0, -2.0, 1.5, 0.0)
    assert grid.is_blocked_xy(np.array([[0.0, -1.0], [5.0, 0.0]])).tolist() == [False, True]


def test_inflation_disc_golden():
    occ = np.zeros((21, 21), dtype=bool)
    occ[10, 10] = True
    grid = OccupancyGrid(np.zeros(2), 0.1, occ)
    # Cells whose centre lies within 0.25 m (2.5 cells) of the obstacle centre: i^2 + j^2 <= 6.25
    # for |i|, |j| <= 2 -> 25 cells minus the 4 corners (8 > 6.25) = 21.
    assert grid.inflate(0.25).occupied_hw.sum() == 21
    assert grid.inflate(0.0).occupied_hw.sum() == 1
    # Exactly 0.2 m (2 cells) is inside: the 13 cells with i^2 + j^2 <= 4.
    assert grid.inflate(0.2).occupied_hw.sum() == 13
    assert grid.occupied_hw.sum() == 1  # the original is untouched


def test_inflation_treats_unknown_as_obstacle_when_asked():
    occ = np.zeros((5, 5), dtype=bool)
    known = np.ones((5, 5), dtype=bool)
    known[0, 0] = False
    grid = OccupancyGrid(np.zeros(2), 1.0, occ, known)
    assert grid.inflate(1.0, unknown_is_free=True).occupied_hw.sum() == 0
    assert grid.inflate(1.0, unknown_is_free=False).occupied_hw.sum() == 3  # (0,0), (0,1), (1,0)


def test_free_components_split_by_wall():
    free = np.ones((5, 7), dtype=bool)
    free[:, 3] = False
    labels, count = free_components(free)
    assert count == 2
    assert labels[0, 0] != labels[0, 6] and labels[2, 3] == 0
    # Touching only at a corner does not connect.
    diag = np.array([[True, False], [False, True]])
    assert free_components(diag)[1] == 2


def _object_grid():
    occ = np.zeros((20, 20), dtype=bool)
    occ[9:12, 9:12] = True  # the object, 0.3 m square around (1.05, 1.05)
    return OccupancyGrid(np.zeros(2), 0.1, occ)


def test_reachable_goal_near_object_golden():
    grid = _object_grid()
    goal = reachable_goal_near(grid, [0.25, 1.05], np.array([[1.05, 1.05]]), standoff=0.25)
    # The four cells next to the block's side centres are 0.2 m from the footprint point;
    # (row 10, col 8) is the one nearest to the start.
    np.testing.assert_allclose(goal, [0.85, 1.05])
    assert reachable_goal_near(grid, [0.25, 1.05], [1.05, 1.05], standoff=0.15) is None


def test_reachable_goal_ignores_walled_off_cells():
    occ = np.zeros((20, 20), dtype=bool)
    occ[5:15, 5] = occ[5:15, 14] = occ[5, 5:15] = occ[14, 5:15] = True  # a closed ring
    occ[9:11, 9:11] = True  # object inside the ring
    grid = OccupancyGrid(np.zeros(2), 0.1, occ)
    footprint = np.array([[1.0, 1.0]])
    assert reachable_goal_near(grid, [0.15, 0.15], footprint, standoff=0.35) is None
    inside = reachable_goal_near(grid, [0.75, 0.75], footprint, standoff=0.35)
    assert inside is not None and np.linalg.norm(inside - footprint[0]) <= 0.35
    # A larger standoff reaches the cells just outside the ring.
    outside = reachable_goal_near(grid, [0.15, 0.15], footprint, standoff=0.75)
    assert outside is not None and not (0.5 <= outside[0] <= 1.5 and 0.5 <= outside[1] <= 1.5)


def test_nearest_free_cell_golden():
    grid = _object_grid()
    np.testing.assert_allclose(nearest_free_cell(grid, [1.05, 1.12]), [1.05, 1.25])
    blocked_start = nearest_free_cell(grid, [0.0, 0.0], reachable_from_xy=[1.05, 1.05])
    assert blocked_start is None


@pytest.mark.parametrize(
    ("points", "match"),
    [
        (np.array([[0.0, 0.0, np.nan]]), "finite"),
        (np.zeros((3, 2)), r"expected shape \(\*, 3\)"),
        (np.zeros((0, 3)), "no points"),
    ],
)
def test_build_rejects_bad_points(points, match):
    with pytest.raises(ValueError, match=match):
        build_occupancy_grid(points)


def test_config_and_grid_validation():
    with pytest.raises(ValueError, match="obstacle_z_min < obstacle_z_max"):
        GridConfig(obstacle_z_min=1.0, obstacle_z_max=0.5)
    with pytest.raises(ValueError, match="resolution"):
        GridConfig(resolution=0.0)
    with pytest.raises(TypeError, match="dtype bool"):
        OccupancyGrid(np.zeros(2), 0.1, np.zeros((3, 3)))
    with pytest.raises(PlannerError, match="known_hw"):
        OccupancyGrid(np.zeros(2), 0.1, np.zeros((3, 3), bool), np.zeros((2, 3), bool))
    with pytest.raises(ValueError, match="radius"):
        _object_grid().inflate(-0.1)
