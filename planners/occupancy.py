"""A 2-D occupancy grid for a mobile base, built from a 3-D point cloud (world frame, z up).

Cell ``(row, col)`` covers ``x in [ox + col*res, ox + (col+1)*res)`` and
``y in [oy + row*res, oy + (row+1)*res)``, with ``(ox, oy) = origin_xy``: rows run along +y,
columns along +x, and a world point falls in the cell ``floor((p - origin) / res)``.

* :class:`GridConfig` / :func:`build_occupancy_grid`: points inside the obstacle height band
  mark cells occupied; points near the floor mark cells observed (``known``).
* :meth:`OccupancyGrid.inflate`: grows blocked cells by the robot radius, so a round base is
  planned as a point.
* :func:`free_components`, :func:`nearest_free_cell`, :func:`reachable_goal_near`: reachability
  and goal selection next to an object.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field, replace

import numpy as np
from numba import njit
from scipy import ndimage

from planners._checks import as_bool_grid, as_float_array, positive_float
from planners.errors import PlannerInputError

__all__ = [
    "GridConfig",
    "OccupancyGrid",
    "build_occupancy_grid",
    "free_components",
    "nearest_free_cell",
    "reachable_goal_near",
]

_LOG = logging.getLogger(__name__)

# 4-connectivity: two cells that touch only at a corner are not connected, matching the planner,
# which accepts a straight segment only when every cell it passes through is free.
_FOUR_CONNECTED = ndimage.generate_binary_structure(2, 1)


@dataclass(frozen=True)
class GridConfig:
    """How a point cloud becomes an occupancy grid."""

    resolution: float = 0.05
    """Cell side in metres."""
    obstacle_z_min: float = 0.1
    """Points at or above this height (m) can block the base; lower points are floor or clutter."""
    obstacle_z_max: float = 1.5
    """Points at or above this height (m) pass over the robot (robot height); they are ignored."""
    floor_z_max: float = 0.05
    """Points below this height (m) are floor: they mark their cell observed (``known``)."""
    min_points: int = 1
    """A cell is occupied when it holds at least this many obstacle-band points (noise filter)."""
    padding: float = 0.0
    """Margin (m) added around the points' xy bounding box when no explicit bounds are given."""

    def __post_init__(self) -> None:
        positive_float("resolution", self.resolution)
        positive_float("padding", self.padding, allow_zero=True)
        for name in ("obstacle_z_min", "obstacle_z_max", "floor_z_max"):
            if not math.isfinite(getattr(self, name)):
                raise PlannerInputError(f"{name}: expected a finite height, got {getattr(self, name)}")
        if not self.obstacle_z_min < self.obstacle_z_max:
            raise PlannerInputError(
                f"obstacle band: expected obstacle_z_min < obstacle_z_max, got "
                f"{self.obstacle_z_min} >= {self.obstacle_z_max}"
            )
        if isinstance(self.min_points, bool) or not isinstance(self.min_points, int) or self.min_points < 1:
            raise PlannerInputError(f"min_points: expected an int >= 1, got {self.min_points!r}")


@dataclass(frozen=True, eq=False)
class OccupancyGrid:
    """A 2-D grid of occupied / observed cells on the floor plane (see the module docstring).

    Shape:
        origin_xy: (2,) world x, y of the outer corner of cell (0, 0).
        occupied_hw: (H, W) bool, True where something blocks the base.
        known_hw: (H, W) bool, True where the cell was observed (floor or obstacle points).
    """

    origin_xy: np.ndarray
    """World (x, y) of the lower-left corner of cell (0, 0), metres."""
    resolution: float
    """Cell side, metres."""
    occupied_hw: np.ndarray
    """True where a cell blocks the base; read-only."""
    known_hw: np.ndarray = field(default=None)  # type: ignore[assignment]
    """True where the cell was observed; defaults to all True (everything known)."""

    def __post_init__(self) -> None:
        origin = as_float_array("origin_xy", self.origin_xy, (2,)).copy()
        origin.setflags(write=False)
        object.__setattr__(self, "origin_xy", origin)
        object.__setattr__(self, "resolution", positive_float("resolution", self.resolution))
        occupied = as_bool_grid("occupied_hw", self.occupied_hw)
        object.__setattr__(self, "occupied_hw", occupied)
        if self.known_hw is None:
            known = np.ones(occupied.shape, dtype=bool)
            known.setflags(write=False)
        else:
            known = as_bool_grid("known_hw", self.known_hw)
            if known.shape != occupied.shape:
                raise PlannerInputError(
                    f"known_hw: expected shape {occupied.shape} like occupied_hw, got {known.shape}"
                )
        object.__setattr__(self, "known_hw", known)

    # -- geometry --------------------------------------------------------------------------

    @property
    def shape(self) -> tuple[int, int]:
        """(H, W): rows along +y, columns along +x."""
        return self.occupied_hw.shape  # type: ignore[return-value]

    @property
    def extent_xy(self) -> tuple[float, float, float, float]:
        """World bounds ``(x_min, y_min, x_max, y_max)`` covered by the grid."""
        h, w = self.shape
        ox, oy = self.origin_xy
        return float(ox), float(oy), float(ox + w * self.resolution), float(oy + h * self.resolution)

    def world_to_cell(self, points_xy) -> np.ndarray:
        """Cell indices ``(row, col)`` of world points; may lie outside the grid.

        Shape:
            points_xy: (N, 2) or (2,) world x, y.
            returns: (N, 2) or (2,) int64 (row, col).
        """
        pts = np.asarray(points_xy, dtype=np.float64)
        single = pts.ndim == 1
        pts = as_float_array("points_xy", pts.reshape(1, -1) if single else pts, (None, 2))
        uv = np.floor((pts - self.origin_xy) / self.resolution).astype(np.int64)
        cells = uv[:, ::-1]
        return cells[0] if single else cells

    def cell_to_world(self, cells_rc) -> np.ndarray:
        """World (x, y) of cell centres.

        Shape:
            cells_rc: (N, 2) or (2,) integer (row, col).
            returns: (N, 2) or (2,) float64 x, y.
        """
        cells = np.asarray(cells_rc)
        single = cells.ndim == 1
        cells = as_float_array("cells_rc", cells.reshape(1, -1) if single else cells, (None, 2))
        xy = self.origin_xy + (cells[:, ::-1] + 0.5) * self.resolution
        return xy[0] if single else xy

    def in_bounds(self, cells_rc) -> np.ndarray:
        """True for cells inside the grid.

        Shape:
            cells_rc: (N, 2) int (row, col). returns: (N,) bool.
        """
        cells = np.asarray(cells_rc).reshape(-1, 2)
        h, w = self.shape
        return (cells[:, 0] >= 0) & (cells[:, 0] < h) & (cells[:, 1] >= 0) & (cells[:, 1] < w)

    # -- traversability --------------------------------------------------------------------

    def blocked_hw(self, *, unknown_is_free: bool = True) -> np.ndarray:
        """Cells the base may not enter: occupied, plus unobserved ones unless ``unknown_is_free``.

        Shape:
            returns: (H, W) bool.
        """
        if unknown_is_free:
            return self.occupied_hw
        return self.occupied_hw | ~self.known_hw

    def is_blocked_xy(self, points_xy, *, unknown_is_free: bool = True) -> np.ndarray:
        """True for world points in a blocked cell or outside the grid.

        Shape:
            points_xy: (N, 2) world x, y. returns: (N,) bool.
        """
        cells = self.world_to_cell(np.asarray(points_xy, dtype=np.float64).reshape(-1, 2))
        inside = self.in_bounds(cells)
        out = np.ones(len(cells), dtype=bool)
        blocked = self.blocked_hw(unknown_is_free=unknown_is_free)
        out[inside] = blocked[cells[inside, 0], cells[inside, 1]]
        return out

    def inflate(self, radius: float, *, unknown_is_free: bool = True) -> "OccupancyGrid":
        """Grow blocked cells by ``radius`` so that a disc of that radius can be planned as a point.

        A cell becomes occupied when its centre lies within ``radius`` of the centre of a blocked
        cell (Euclidean, exact distance transform). Obstacles are represented by cell centres, so
        pass ``radius + resolution / 2`` for a clearance measured to cell edges. With
        ``unknown_is_free=False`` unobserved cells are inflated like obstacles. ``known_hw`` is
        kept unchanged.
        """
        radius = positive_float("radius", radius, allow_zero=True)
        blocked = self.blocked_hw(unknown_is_free=unknown_is_free)
        if not blocked.any():
            return replace(self, occupied_hw=blocked.copy())
        dist = ndimage.distance_transform_edt(~blocked, sampling=self.resolution)
        # A small tolerance keeps cells at exactly `radius` (common for grid-aligned radii) blocked.
        inflated = dist <= radius + 1e-9 * self.resolution
        return replace(self, occupied_hw=inflated)


def build_occupancy_grid(
    points_world_n3,
    config: GridConfig | None = None,
    *,
    bounds_xy: tuple[float, float, float, float] | None = None,
) -> OccupancyGrid:
    """Rasterise a world-frame point cloud (z up) into an :class:`OccupancyGrid`.

    Points with ``obstacle_z_min <= z < obstacle_z_max`` count towards occupancy; points with
    ``z < floor_z_max`` and occupied cells mark cells observed. Points outside ``bounds_xy``
    are dropped. Without ``bounds_xy`` the grid covers the xy bounding box of all points plus
    ``config.padding``.

    Shape:
        points_world_n3: (N, 3) world x, y, z in metres, N >= 1.
        bounds_xy: (x_min, y_min, x_max, y_max) in metres.
    """
    config = GridConfig() if config is None else config
    if not isinstance(config, GridConfig):
        raise TypeError(f"config: expected a GridConfig, got {type(config).__name__}")
    pts = as_float_array("points_world_n3", points_world_n3, (None, 3))
    if bounds_xy is None:
        if len(pts) == 0:
            raise PlannerInputError("points_world_n3: no points and no bounds_xy, cannot size the grid")
        # Column by column: numpy reduces a strided (N, 2) view along axis 0 ten times slower.
        lo = np.array([pts[:, 0].min(), pts[:, 1].min()]) - config.padding
        hi = np.array([pts[:, 0].max(), pts[:, 1].max()]) + config.padding
    else:
        b = as_float_array("bounds_xy", bounds_xy, (4,))
        lo, hi = b[:2], b[2:]
        if not np.all(hi > lo):
            raise PlannerInputError(f"bounds_xy: expected x_min < x_max and y_min < y_max, got {tuple(b)}")
    res = config.resolution
    if bounds_xy is None:
        # One more cell than the span so that the points on the upper edge get a cell too.
        w, h = np.floor((hi - lo) / res).astype(np.int64) + 1
    else:
        w, h = np.maximum(np.ceil((hi - lo) / res - 1e-9).astype(np.int64), 1)
    counts, floor = _rasterise(np.ascontiguousarray(pts), float(lo[0]), float(lo[1]), float(res), int(h), int(w),
                               float(config.obstacle_z_min), float(config.obstacle_z_max), float(config.floor_z_max))
    occupied = (counts >= config.min_points).reshape(h, w)
    known = floor.reshape(h, w) | occupied
    _LOG.debug("occupancy grid %dx%d at %.3f m: %d occupied, %d known", h, w, res, occupied.sum(), known.sum())
    return OccupancyGrid(origin_xy=lo, resolution=res, occupied_hw=occupied, known_hw=known)


@njit(cache=True, nogil=True)
def _rasterise(pts, lo_x, lo_y, res, h, w, z_min, z_max, floor_z_max):
    """Per cell of an (h, w) grid: the obstacle-band points (``z_min <= z < z_max``) and whether
    a floor point (``z < floor_z_max``) fell in it, in one pass; points outside are skipped.
    A point's cell is ``floor((p - lo) / res)`` in float64, as the module docstring says.

    Shape:
        pts (N, 3) float64 -> counts (h * w,) int64, floor (h * w,) bool.
    """
    counts = np.zeros(h * w, np.int64)
    floor = np.zeros(h * w, np.bool_)
    for i in range(pts.shape[0]):
        col = np.int64(np.floor((pts[i, 0] - lo_x) / res))
        row = np.int64(np.floor((pts[i, 1] - lo_y) / res))
        if row < 0 or row >= h or col < 0 or col >= w:
            continue
        z = pts[i, 2]
        cell = row * w + col
        if z >= z_min and z < z_max:
            counts[cell] += 1
        if z < floor_z_max:
            floor[cell] = True
    return counts, floor


def free_components(free_hw: np.ndarray) -> tuple[np.ndarray, int]:
    """Label 4-connected components of free cells (0 = blocked, 1..K = components).

    Shape:
        free_hw: (H, W) bool. returns: ((H, W) int32 labels, K).
    """
    free = as_bool_grid("free_hw", free_hw)
    labels, count = ndimage.label(free, structure=_FOUR_CONNECTED)
    return labels.astype(np.int32, copy=False), int(count)


def _component_mask(grid: OccupancyGrid, start_xy, unknown_is_free: bool) -> np.ndarray | None:
    """Free cells reachable from ``start_xy`` (None when the start cell is blocked)."""
    free = ~grid.blocked_hw(unknown_is_free=unknown_is_free)
    cell = grid.world_to_cell(as_float_array("start_xy", start_xy, (2,)))
    if not grid.in_bounds(cell)[0] or not free[cell[0], cell[1]]:
        return None
    labels, _ = free_components(free)
    return labels == labels[cell[0], cell[1]]


def nearest_free_cell(
    grid: OccupancyGrid,
    point_xy,
    *,
    reachable_from_xy=None,
    unknown_is_free: bool = True,
) -> np.ndarray | None:
    """Centre of the free cell nearest to ``point_xy`` (ties: lowest row, then column).

    With ``reachable_from_xy`` only cells connected to that start count. Returns None when no
    cell qualifies (no free cell, or the start itself is blocked).

    Shape:
        point_xy: (2,). reachable_from_xy: (2,) or None. returns: (2,) world x, y, or None.
    """
    point = as_float_array("point_xy", point_xy, (2,))
    if reachable_from_xy is None:
        mask = ~grid.blocked_hw(unknown_is_free=unknown_is_free)
    else:
        mask = _component_mask(grid, reachable_from_xy, unknown_is_free)
        if mask is None:
            return None
    cells = np.argwhere(mask)
    if len(cells) == 0:
        return None
    centres = grid.cell_to_world(cells)
    d2 = np.sum((centres - point) ** 2, axis=1)
    return centres[int(np.argmin(d2))]


def reachable_goal_near(
    grid: OccupancyGrid,
    start_xy,
    footprint_xy,
    *,
    standoff: float,
    unknown_is_free: bool = True,
) -> np.ndarray | None:
    """A goal for the base next to an object: free, reachable from the start, close to the object.

    Candidates are free cells (of an already inflated grid) connected to the start cell whose
    centre lies within ``standoff`` metres of the object's footprint (the nearest footprint
    point). Of those, the one closest to the footprint wins; ties go to the one closest to the
    start. ``standoff`` is measured from the robot centre, so it must exceed the inflation
    radius for any cell to qualify. Returns None (and logs why) when nothing qualifies.

    Shape:
        start_xy: (2,) world x, y of the robot.
        footprint_xy: (M, 2) world x, y of the object's points projected on the floor (M >= 1);
            a single (2,) centre is accepted too.
        returns: (2,) world x, y of the chosen cell centre, or None.
    """
    from scipy.spatial import cKDTree

    standoff = positive_float("standoff", standoff)
    footprint = np.asarray(footprint_xy, dtype=np.float64) if isinstance(footprint_xy, (list, tuple)) else footprint_xy
    if isinstance(footprint, np.ndarray) and footprint.ndim == 1:
        footprint = footprint.reshape(1, -1)
    footprint = as_float_array("footprint_xy", footprint, (None, 2))
    if len(footprint) == 0:
        raise PlannerInputError("footprint_xy: expected at least one point, got none")
    start = as_float_array("start_xy", start_xy, (2,))
    mask = _component_mask(grid, start, unknown_is_free)
    if mask is None:
        _LOG.info("no goal near the object: the start %s is blocked or outside the grid", start.tolist())
        return None
    # Only cells inside the footprint's bounding box grown by the standoff can qualify.
    h, w = grid.shape
    r0, c0 = np.maximum(grid.world_to_cell(footprint.min(axis=0) - standoff), 0)
    r1, c1 = np.minimum(grid.world_to_cell(footprint.max(axis=0) + standoff) + 1, (h, w))
    cells = np.argwhere(mask[r0:r1, c0:c1]) + np.array([r0, c0])
    if len(cells) == 0:
        _LOG.info("no reachable free cell within %.3f m of the object's bounding box", standoff)
        return None
    centres = grid.cell_to_world(cells)
    reach = standoff * (1.0 + 1e-9) + 1e-12  # a cell at exactly `standoff` qualifies despite round-off
    dist, _ = cKDTree(footprint).query(centres, k=1, distance_upper_bound=reach)
    near = dist <= reach
    if not near.any():
        _LOG.info("no reachable free cell within %.3f m of the object", standoff)
        return None
    centres, dist = centres[near], dist[near]
    to_start = np.linalg.norm(centres - start, axis=1)
    best = np.lexsort((to_start, np.round(dist / grid.resolution, 6)))[0]
    return centres[best]
