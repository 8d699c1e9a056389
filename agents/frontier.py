"""Frontier-based exploration targets on an occupancy grid (Yamauchi 1997).

A frontier cell is an observed free cell with an unobserved 4-neighbour (unobserved cells within
two cells of an obstacle excepted): driving there reveals new space. Frontier cells are grouped into 8-connected clusters; small clusters (sensor
speckle) are dropped, and each cluster offers the free cell nearest to its centroid as a target.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from planners.occupancy import OccupancyGrid, free_components

__all__ = ["Frontier", "find_frontiers", "choose_frontier"]


@dataclass(frozen=True)
class Frontier:
    """One frontier cluster.

    Shape:
        target_xy: (2,) world x, y of the reachable free cell nearest the cluster centroid.
    """

    target_xy: np.ndarray
    size: int
    """Number of frontier cells (how much unknown border it opens)."""


def find_frontiers(
    grid: OccupancyGrid, start_xy, *, inflated: OccupancyGrid | None = None, min_cells: int = 6
) -> list[Frontier]:
    """Frontier clusters whose targets the base can reach from ``start_xy``.

    Args:
        grid: the raw grid (occupied + known cells).
        start_xy: the robot position, (2,).
        inflated: the grid inflated by the robot radius (reachability and targets use it);
            defaults to ``grid``.
        min_cells: clusters smaller than this are ignored.
    """
    inflated = grid if inflated is None else inflated
    known, occupied = grid.known_hw, grid.occupied_hw
    free_known = known & ~occupied
    # Unobserved cells hugging an obstacle (the floor strip at a wall's foot) open nothing.
    unknown = ~known & ~ndimage.binary_dilation(occupied, iterations=2)
    pad = np.pad(unknown, 1, constant_values=True)  # beyond the grid is unobserved too
    near_unknown = pad[:-2, 1:-1] | pad[2:, 1:-1] | pad[1:-1, :-2] | pad[1:-1, 2:]
    frontier = free_known & near_unknown
    labels, count = ndimage.label(frontier, structure=np.ones((3, 3), bool))
    if count == 0:
        return []
    # The base may cross unobserved cells (its own footprint is usually unseen), but targets
    # must be observed free cells it can reach.
    comp, _ = free_components(~inflated.blocked_hw(unknown_is_free=True))
    cell = grid.world_to_cell(np.asarray(start_xy, np.float64))
    if not grid.in_bounds(cell[None])[0] or comp[cell[0], cell[1]] == 0:
        return []
    reachable = (comp == comp[cell[0], cell[1]]) & known
    reach_cells = np.argwhere(reachable)
    if len(reach_cells) == 0:
        return []
    out = []
    sizes = ndimage.sum_labels(frontier, labels, index=np.arange(1, count + 1))
    centroids = ndimage.center_of_mass(frontier, labels, index=np.arange(1, count + 1))
    for size, (r, c) in zip(sizes, centroids):
        if size < min_cells:
            continue
        d2 = (reach_cells[:, 0] - r) ** 2 + (reach_cells[:, 1] - c) ** 2
        best = reach_cells[int(np.argmin(d2))]
        if np.sqrt(d2.min()) * grid.resolution > 1.5:  # the cluster is not approachable from here
            continue
        out.append(Frontier(grid.cell_to_world(best), int(size)))
    return out


def choose_frontier(frontiers: list[Frontier], position_xy, visited_xy=(), *, visited_radius: float = 0.6) -> Frontier | None:
    """The frontier to explore next: nearest (Euclidean) per unit of size^0.5, skipping targets
    within ``visited_radius`` of earlier targets (so the base does not circle one spot)."""
    pos = np.asarray(position_xy, np.float64)
    visited = np.asarray(list(visited_xy), np.float64).reshape(-1, 2)
    best, best_cost = None, np.inf
    for f in frontiers:
        if len(visited) and np.min(np.linalg.norm(visited - f.target_xy, axis=1)) < visited_radius:
            continue
        cost = (np.linalg.norm(f.target_xy - pos) + 0.5) / np.sqrt(f.size)
        if cost < best_cost:
            best, best_cost = f, cost
    return best
