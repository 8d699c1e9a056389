"""The space a navigator that looks again (``look_again``, the map-free twin) counts as explored
for frontiers once a later goal of a chain is revealed: only what its frames show from then on,
within the map's depth range; the map navigator's frontiers are found on its whole grid."""

from __future__ import annotations

import dataclasses

import numpy as np

from agents.frontier import find_frontiers
from agents.navigator import MapNavigator, NavigatorConfig
from planners.occupancy import build_occupancy_grid


class _NoMapper:
    """Only the map's depth range, which bounds the space a frame shows."""

    privileged = False
    config = type("C", (), {"max_depth": 1.5})()


def _looking_again(agent: MapNavigator) -> MapNavigator:
    """``agent`` as it is right after a later goal was revealed with ``look_again``."""
    agent._looking_again = True
    return agent


def _looking_down(height: float = 1.0, x: float = 0.0) -> dict:
    """A 40x40 frame from ``height`` m above (x, 0), looking straight down at a flat floor."""
    T = np.eye(4)
    T[:3, :3] = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])  # columns: camera x, y, z in the world
    T[:3, 3] = [x, 0.0, height]
    K = np.array([[20.0, 0.0, 19.5], [0.0, 20.0, 19.5], [0.0, 0.0, 1.0]])
    return {"depth": np.full((40, 40), height, np.float32), "K": K, "cam_to_world": T}


def _floor_grid(config: NavigatorConfig, half: float = 3.0):
    """A grid whose every cell is observed floor, ``half`` m either side of the origin."""
    xs = np.arange(-half, half, config.grid.resolution / 2)
    xx, yy = np.meshgrid(xs, xs)
    pts = np.stack([xx.ravel(), yy.ravel(), np.zeros(xx.size)], axis=1)
    return build_occupancy_grid(pts, dataclasses.replace(config.grid, padding=0.0))


def test_the_map_navigator_finds_frontiers_on_its_whole_grid():
    agent = MapNavigator(_NoMapper(), NavigatorConfig())
    grid = _floor_grid(agent.config)
    assert agent._frontier_grid(grid) is grid


def test_only_what_was_seen_since_within_the_depth_range_counts_as_explored():
    config = NavigatorConfig(look_again=True)
    agent = _looking_again(MapNavigator(_NoMapper(), config))
    agent._see_close(_looking_down(height=2.0))  # beyond the map's depth range: nothing seen
    assert len(agent._close_keys) == 0
    agent._see_close(_looking_down(height=1.0))  # footprint 2 m x 2 m around the origin
    grid = _floor_grid(config)
    narrowed = agent._frontier_grid(grid)
    assert grid.known_hw.all()
    known_xy = grid.cell_to_world(np.argwhere(narrowed.known_hw))
    assert np.abs(known_xy).max() <= 1.0 + config.grid.resolution
    # the whole footprint is covered (no holes from the lattice), nothing outside it
    inner = grid.cell_to_world(np.argwhere(np.ones(grid.shape, bool)))
    inside = np.all(np.abs(inner) < 0.85, axis=1)
    assert narrowed.known_hw.reshape(-1)[inside].all()
    # frontiers now run along the edge of the close footprint (about 4 x 40 cells), not only the
    # map's far border (4 x 120 cells)
    far = find_frontiers(grid, np.zeros(2))
    near = find_frontiers(narrowed, np.zeros(2))
    assert near and all(np.abs(f.target_xy).max() <= 1.1 for f in near)
    assert 120 <= sum(f.size for f in near) <= 200 < sum(f.size for f in far)


def test_seen_space_accumulates_over_frames():
    agent = _looking_again(MapNavigator(_NoMapper(), NavigatorConfig(look_again=True)))
    agent._see_close(_looking_down(x=0.0))
    one = len(agent._close_keys)
    agent._see_close(_looking_down(x=0.0))
    assert len(agent._close_keys) == one  # the same view adds nothing
    agent._see_close(_looking_down(x=-1.5))  # negative world coordinates round-trip too
    narrowed = agent._frontier_grid(_floor_grid(agent.config))
    xy = narrowed.cell_to_world(np.argwhere(narrowed.known_hw))
    assert xy[:, 0].min() < -2.3 and xy[:, 0].max() > 0.9
