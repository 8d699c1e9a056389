"""Exact grid traversal of straight segments: which cells does a segment pass through?

A segment is free when every cell it passes through is free. :func:`segment_cells` lists those
cells in closed form (the parameters where the segment crosses grid lines, then the cell of each
piece at its midpoint). :class:`SegmentChecker` is the fast scalar walk the planners call
thousands of times (grid walk with early exit); where a segment passes through a cell corner,
or within round-off of one, it also requires both side cells to be free, so it is never more
permissive than :func:`segment_cells`. The 2-D planner checks motions with it, and
:func:`path_blocked_segments` re-checks paths with it.
"""

from __future__ import annotations

import math

import numpy as np

from planners._checks import as_float_array
from planners.occupancy import OccupancyGrid

__all__ = ["segment_cells", "segment_is_free", "path_blocked_segments", "SegmentChecker"]

# Crossing parameters closer than this (fractions of the segment) count as one corner crossing.
_TIE = 1e-9


def _traverse(u0: float, v0: float, u1: float, v1: float) -> tuple[np.ndarray, np.ndarray]:
    """Columns and rows of the cells a segment crosses, in order, in cell units (may repeat)."""
    du, dv = u1 - u0, v1 - v0
    parts = [np.zeros(1), np.ones(1)]
    if du != 0.0:
        ks = np.arange(math.floor(min(u0, u1)) + 1, math.ceil(max(u0, u1)), dtype=np.float64)
        parts.append((ks - u0) / du)
    if dv != 0.0:
        ks = np.arange(math.floor(min(v0, v1)) + 1, math.ceil(max(v0, v1)), dtype=np.float64)
        parts.append((ks - v0) / dv)
    t = np.sort(np.concatenate(parts))
    mid = 0.5 * (t[:-1] + t[1:])
    cols = np.floor(u0 + mid * du).astype(np.int64)
    rows = np.floor(v0 + mid * dv).astype(np.int64)
    return rows, cols


class SegmentChecker:
    """Checks points and segments against a fixed blocked mask (fast path for planners).

    Outside the grid counts as blocked.

    Shape:
        blocked_hw: (H, W) bool. origin_xy: (2,) world x, y of cell (0, 0)'s corner.
    """

    def __init__(self, blocked_hw: np.ndarray, origin_xy: np.ndarray, resolution: float) -> None:
        self._blocked = np.ascontiguousarray(blocked_hw, dtype=bool)
        self._h, self._w = self._blocked.shape
        # Flat bytes index faster than a 2-D ndarray for the scalar point test.
        self._flat = self._blocked.tobytes()
        self._ox = float(origin_xy[0])
        self._oy = float(origin_xy[1])
        self._res = float(resolution)

    def point_free(self, x: float, y: float) -> bool:
        """True when the world point (x, y) lies in a free cell of the grid."""
        u = (x - self._ox) / self._res
        v = (y - self._oy) / self._res
        if not (0.0 <= u < self._w and 0.0 <= v < self._h):
            return False
        return not self._flat[int(v) * self._w + int(u)]

    def segment_free(self, x0: float, y0: float, x1: float, y1: float) -> bool:
        """True when every cell the segment (x0, y0)-(x1, y1) passes through is free.

        Scalar grid walk (Amanatides-Woo) with an early exit at the first blocked cell; where
        the segment passes exactly through a cell corner, both side cells must be free too.
        """
        if not (self.point_free(x0, y0) and self.point_free(x1, y1)):
            return False
        u0, v0 = (x0 - self._ox) / self._res, (y0 - self._oy) / self._res
        u1, v1 = (x1 - self._ox) / self._res, (y1 - self._oy) / self._res
        c, r = int(u0), int(v0)
        c1, r1 = int(u1), int(v1)
        if c == c1 and r == r1:
            return True
        sc, t_c, dt_c = _axis_walk(u0, u1 - u0, c)
        sr, t_r, dt_r = _axis_walk(v0, v1 - v0, r)
        flat, w = self._flat, self._w
        # Every step moves towards the end cell, so the walk stays inside the bounding box of
        # the two end cells (inside the grid) and ends after at most |dc| + |dr| steps.
        while c != c1 or r != r1:
            if r == r1 or (c != c1 and t_c < t_r - _TIE):
                c += sc
                t_c += dt_c
            elif c == c1 or t_r < t_c - _TIE:
                r += sr
                t_r += dt_r
            else:  # through (or within round-off of) a corner: both side cells count as touched
                if flat[r * w + c + sc] or flat[(r + sr) * w + c]:
                    return False
                c += sc
                r += sr
                t_c += dt_c
                t_r += dt_r
            if flat[r * w + c]:
                return False
        return True


def segment_cells(grid: OccupancyGrid, a_xy, b_xy) -> np.ndarray:
    """Cells ``(row, col)`` the segment from ``a_xy`` to ``b_xy`` passes through, in order.

    Cells outside the grid are included (they have out-of-range indices).

    Shape:
        a_xy, b_xy: (2,) world x, y. returns: (K, 2) int64, K >= 1, without repeats.
    """
    a = as_float_array("a_xy", a_xy, (2,))
    b = as_float_array("b_xy", b_xy, (2,))
    ua, va = (a - grid.origin_xy) / grid.resolution
    ub, vb = (b - grid.origin_xy) / grid.resolution
    rows, cols = _traverse(ua, va, ub, vb)
    cells = np.stack([rows, cols], axis=1)
    keep = np.ones(len(cells), dtype=bool)
    keep[1:] = np.any(cells[1:] != cells[:-1], axis=1)
    return cells[keep]


def segment_is_free(grid: OccupancyGrid, a_xy, b_xy, *, unknown_is_free: bool = True) -> bool:
    """True when every cell the segment passes through is inside the grid and not blocked."""
    cells = segment_cells(grid, a_xy, b_xy)
    if not grid.in_bounds(cells).all():
        return False
    blocked = grid.blocked_hw(unknown_is_free=unknown_is_free)
    return not blocked[cells[:, 0], cells[:, 1]].any()


def path_blocked_segments(grid: OccupancyGrid, path_xy, *, unknown_is_free: bool = True) -> np.ndarray:
    """Which segments of a polyline pass through a blocked cell or leave the grid.

    A single-point path gives one entry: whether that point is blocked.

    Shape:
        path_xy: (N, 2) world x, y, N >= 1. returns: (max(N - 1, 1),) bool.
    """
    path = as_float_array("path_xy", path_xy, (None, 2))
    if len(path) == 0:
        raise ValueError("path_xy: expected at least one waypoint, got none")
    checker = SegmentChecker(grid.blocked_hw(unknown_is_free=unknown_is_free), grid.origin_xy, grid.resolution)
    if len(path) == 1:
        return np.array([not checker.point_free(*path[0])])
    return np.array([not checker.segment_free(*p, *q) for p, q in zip(path[:-1], path[1:])], dtype=bool)


def _axis_walk(start: float, delta: float, cell: int) -> tuple[int, float, float]:
    """Along one grid axis of a segment ``start -> start + delta`` that begins in ``cell``: the
    step (+1, -1 or 0), the segment parameter of the first cell boundary crossed, and the
    parameter increment between boundaries (``inf`` when the segment does not move along it)."""
    if delta > 0.0:
        return 1, (cell + 1 - start) / delta, 1.0 / delta
    if delta < 0.0:
        return -1, (start - cell) / -delta, -1.0 / delta
    return 0, math.inf, math.inf
