"""Frontier targets on occupancy grids built from point clouds."""

import numpy as np

from agents.frontier import choose_frontier, find_frontiers
from planners.occupancy import GridConfig, build_occupancy_grid


def _grid(floor_x_max=2.0):
    xs, ys = np.meshgrid(np.arange(0, floor_x_max, 0.02), np.arange(0, 2.0, 0.02))
    floor = np.stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)], 1)
    wall_y = np.arange(0, 4.0, 0.02)
    wall = np.stack([np.full_like(wall_y, -0.05), wall_y, np.full_like(wall_y, 0.5)], 1)  # wall at x = -0.05
    pts = np.concatenate([floor, wall])
    return build_occupancy_grid(pts, GridConfig(resolution=0.05, padding=0.0), bounds_xy=(-0.5, -0.5, 4.0, 4.0))


def test_frontiers_lie_on_the_border_of_the_observed_floor():
    grid = _grid()
    inflated = grid.inflate(0.2)
    fronts = find_frontiers(grid, (1.0, 1.0), inflated=inflated)
    assert fronts, "an observed 2x2 m patch inside a 4.5 m grid must have frontiers"
    for f in fronts:
        x, y = f.target_xy
        assert -0.1 <= x <= 2.1 and -0.1 <= y <= 2.1  # targets are inside the observed, reachable part
        assert not inflated.is_blocked_xy(f.target_xy[None])[0]
    # No frontier towards the wall side (x < 0 is blocked, not unknown-and-reachable).
    assert all(f.target_xy[0] > 0.15 for f in fronts)


def test_choose_frontier_prefers_near_and_skips_visited():
    grid = _grid()
    fronts = find_frontiers(grid, (1.0, 1.0), inflated=grid.inflate(0.2))
    first = choose_frontier(fronts, (1.9, 1.0))
    assert first is not None
    second = choose_frontier(fronts, (1.9, 1.0), visited_xy=[first.target_xy], visited_radius=0.6)
    assert second is None or np.linalg.norm(second.target_xy - first.target_xy) >= 0.6


def test_fully_observed_room_has_no_frontier():
    xs, ys = np.meshgrid(np.arange(0, 2.0, 0.02), np.arange(0, 2.0, 0.02))
    floor = np.stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)], 1)
    ring = []
    for t in np.arange(-0.1, 2.1, 0.02):
        ring += [(t, -0.1, 0.5), (t, 2.05, 0.5), (-0.1, t, 0.5), (2.05, t, 0.5)]
    grid = build_occupancy_grid(np.concatenate([floor, np.array(ring)]), GridConfig(resolution=0.05))
    assert find_frontiers(grid, (1.0, 1.0), inflated=grid.inflate(0.2)) == []
