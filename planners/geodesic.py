"""Geodesic distances over a 2-D grid of free cells: the shortest 8-connected path length.

Used to score object search (SPL's shortest path), to check that search episodes are solvable,
and by the privileged search agent to walk down to its goal. Inputs are numpy grids; the grid's
frame is ``origin`` (world x, y of cell ``[0, 0]``'s lower corner) and ``cell`` (metres): cell
``[r, c]`` covers x in ``origin[0] + [c, c + 1) * cell`` and y in ``origin[1] + [r, r + 1) * cell``.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

__all__ = ["geodesic_field", "geodesic_to_goal"]


def geodesic_field(free_hw: np.ndarray, goal_hw: np.ndarray, cell: float) -> np.ndarray:
    """Shortest 8-connected path length (m) over free cells from every cell to the nearest goal
    cell (``inf`` where no goal cell is reachable, and on blocked cells).

    Shape:
        free_hw, goal_hw: (H, W) bool; returns (H, W) float64.
    """
    h, w = free_hw.shape
    idx = np.full((h, w), -1, np.int64)
    cells = np.argwhere(free_hw)
    idx[cells[:, 0], cells[:, 1]] = np.arange(len(cells))
    out = np.full((h, w), np.inf)
    sources = idx[goal_hw & free_hw]
    if len(sources) == 0:
        return out
    rows, cols, weights = [], [], []
    for dr, dc in ((0, 1), (1, 0), (1, 1), (1, -1)):
        c0, c1 = max(0, -dc), w - max(0, dc)
        a = idx[0 : h - dr, c0:c1]
        b = idx[dr:h, c0 + dc : c1 + dc]
        ok = (a >= 0) & (b >= 0)
        rows.append(a[ok]), cols.append(b[ok]), weights.append(np.full(int(ok.sum()), cell * math.hypot(dr, dc)))
    n = len(cells)
    graph = coo_matrix((np.concatenate(weights), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n)).tocsr()
    out[cells[:, 0], cells[:, 1]] = dijkstra(graph, directed=False, indices=sources, min_only=True)
    return out


def geodesic_to_goal(free_hw: np.ndarray, origin, cell: float, start_xy, goal_mask_hw: np.ndarray) -> float:
    """Shortest 8-connected path length (m) over free cells from ``start_xy`` to any goal cell.

    ``inf`` when no goal cell is reachable (or the start is off the grid or on a blocked cell).

    Shape:
        free_hw, goal_mask_hw: (H, W) bool; origin, start_xy: (2,).
    """
    h, w = free_hw.shape
    r, c = (np.floor((np.asarray(start_xy) - origin) / cell).astype(int))[::-1]
    if not (0 <= r < h and 0 <= c < w) or not free_hw[r, c]:
        return math.inf
    return float(geodesic_field(free_hw, goal_mask_hw, cell)[r, c])
