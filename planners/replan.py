"""Deciding when a path has become blocked, so that an agent replans.

The map grows while the robot drives: an obstacle seen late can land on the remaining path.
:func:`check_path_blocked` re-checks only what is still ahead (from the robot's projection on
the path) against the current, inflated grid, with the same exact segment traversal the
planner used.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planners._checks import as_float_array, positive_float
from planners.errors import PlannerInputError, PlannerTypeError
from planners.occupancy import OccupancyGrid
from planners.raycast import SegmentChecker

__all__ = ["BlockedCheck", "check_path_blocked", "remaining_path"]


@dataclass(frozen=True, eq=False)
class BlockedCheck:
    """Whether the path ahead is blocked and where.

    Shape:
        blocked_xy: (2,) world x, y of the first blocked point found ahead, or None.
    """

    blocked: bool
    """True when some part of the path ahead crosses a blocked cell: replan."""
    segment_index: int | None
    """Index i of the first blocked segment path[i] -> path[i+1] (None when clear)."""
    distance_ahead: float | None
    """Arc length from the robot's projection to the start of that blocked segment, metres."""
    blocked_xy: np.ndarray | None
    """First blocked sample point (0.25-cell steps) on that segment."""


def remaining_path(path_xy, position_xy) -> tuple[np.ndarray, int]:
    """The part of a path ahead of a position: its projection, then the waypoints after it.

    Returns the remaining polyline and the index of the segment the projection lies on.

    Shape:
        path_xy: (N, 2), N >= 2. position_xy: (2,). returns: ((M, 2), int), M >= 2.
    """
    path = as_float_array("path_xy", path_xy, (None, 2))
    if len(path) < 2:
        raise PlannerInputError(f"path_xy: expected at least two waypoints, got {len(path)}")
    pos = as_float_array("position_xy", position_xy, (2,))
    a, d = path[:-1], np.diff(path, axis=0)
    len2 = np.einsum("ij,ij->i", d, d)
    t = np.where(len2 > 0.0, np.einsum("ij,ij->i", pos - a, d) / np.where(len2 > 0, len2, 1.0), 0.0)
    proj = a + np.clip(t, 0.0, 1.0)[:, None] * d
    i = int(np.argmin(np.linalg.norm(proj - pos, axis=1)))
    return np.vstack([proj[i], path[i + 1 :]]), i


def check_path_blocked(
    grid: OccupancyGrid,
    path_xy,
    *,
    position_xy=None,
    skip_distance: float = 0.0,
    horizon: float | None = None,
    unknown_is_free: bool = True,
) -> BlockedCheck:
    """Check the path ahead of the robot against an (inflated) grid.

    Args:
        grid: the current occupancy grid, inflated by the robot radius.
        path_xy: the path being followed.
        position_xy: the robot's position; None checks the whole path.
        skip_distance: ignore the first metres ahead of the projection (the robot's own cell can
            turn blocked when an obstacle appears right next to it; replanning would then answer
            ``"start_in_collision"`` anyway).
        horizon: only check this many metres ahead (None: to the goal).
        unknown_is_free: whether unobserved cells may be crossed.

    Shape:
        path_xy: (N, 2), N >= 2. position_xy: (2,) or None.
    """
    if not isinstance(grid, OccupancyGrid):
        raise PlannerTypeError(f"grid: expected an OccupancyGrid, got {type(grid).__name__}")
    path = as_float_array("path_xy", path_xy, (None, 2))
    skip_distance = positive_float("skip_distance", skip_distance, allow_zero=True)
    if horizon is not None:
        horizon = positive_float("horizon", horizon)
    if position_xy is None:
        if len(path) < 2:
            raise PlannerInputError(f"path_xy: expected at least two waypoints, got {len(path)}")
        ahead, offset = path, 0
    else:
        ahead, offset = remaining_path(path, position_xy)

    seg = np.diff(ahead, axis=0)
    seg_len = np.linalg.norm(seg, axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg_len)])
    end = cum[-1] if horizon is None else min(cum[-1], skip_distance + horizon)
    checker = SegmentChecker(grid.blocked_hw(unknown_is_free=unknown_is_free), grid.origin_xy, grid.resolution)
    step = 0.25 * grid.resolution
    for k in range(len(seg)):
        s0, s1 = max(cum[k], skip_distance), min(cum[k + 1], end)
        if s1 < s0 or seg_len[k] == 0.0:
            continue
        p = ahead[k] + (s0 - cum[k]) / seg_len[k] * seg[k]
        q = ahead[k] + (s1 - cum[k]) / seg_len[k] * seg[k]
        if checker.segment_free(*p, *q):
            continue
        # Locate the first blocked point for the report (sampling is enough for a report).
        n = max(int(np.ceil((s1 - s0) / step)), 1)
        samples = p + np.linspace(0.0, 1.0, n + 1)[:, None] * (q - p)
        hits = grid.is_blocked_xy(samples, unknown_is_free=unknown_is_free)
        hit = samples[int(np.argmax(hits))] if hits.any() else samples[0]
        return BlockedCheck(True, offset + k, float(max(cum[k], skip_distance)), hit.copy())
    return BlockedCheck(False, None, None, None)
