"""3D regions of a map: the answer to "where is X?".

A :class:`Region` is a spatially connected set of map points that a query selected. It is a
plain container: the spatial comparators, the agents and the evaluation code read its
geometry and never need the map it came from.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from conceptfusion._checks import as_array, as_float_array
from conceptfusion.errors import ShapeError

__all__ = ["Region", "region_from_points", "SupportTest", "drop_support", "support_mask"]


@dataclass(frozen=True)
class Region:
    """A connected set of map points selected by a query.

    Shape:
        ``indices_n`` (N,) int64 map point indices (empty when built from bare points),
        ``points_n3`` (N, 3) float64 world positions, ``scores_n`` (N,) float32.
    """

    points_n3: np.ndarray
    """World positions of the region's points, metres."""
    scores_n: np.ndarray
    """Per-point query score of the region's points."""
    indices_n: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    """Indices of the points in the map they came from (empty if unknown)."""

    @property
    def num_points(self) -> int:
        return int(self.points_n3.shape[0])

    @property
    def centroid(self) -> np.ndarray:
        """Mean position, (3,)."""
        return self.points_n3.mean(axis=0)

    @property
    def median(self) -> np.ndarray:
        """Per-axis median position, (3,): robust to stray points (the paper's object position)."""
        return np.median(self.points_n3, axis=0)

    @property
    def aabb_min(self) -> np.ndarray:
        """Axis-aligned box lower corner, (3,)."""
        return self.points_n3.min(axis=0)

    @property
    def aabb_max(self) -> np.ndarray:
        """Axis-aligned box upper corner, (3,)."""
        return self.points_n3.max(axis=0)

    @property
    def extent(self) -> np.ndarray:
        """Axis-aligned box size, (3,)."""
        return self.aabb_max - self.aabb_min

    @property
    def score(self) -> float:
        """Mean score of the region's points."""
        return float(np.mean(self.scores_n)) if self.scores_n.size else float("nan")


def region_from_points(points_n3, scores_n=None, indices_n=None) -> Region:
    """Build a :class:`Region` from bare points (scores default to 1).

    Shape:
        ``points_n3`` (N, 3) with N >= 1; ``scores_n`` (N,); ``indices_n`` (N,).
    """
    pts = as_float_array("points_n3", np.asarray(points_n3, dtype=np.float64), shape=(None, 3))
    if pts.shape[0] == 0:
        raise ShapeError("points_n3: expected at least one point, got 0")
    scores = np.ones(len(pts), np.float32) if scores_n is None else np.asarray(scores_n, np.float32)
    if scores.shape != (len(pts),):
        raise ShapeError(f"scores_n: expected shape ({len(pts)},), got {scores.shape}")
    idx = np.zeros(0, np.int64) if indices_n is None else np.asarray(indices_n, np.int64)
    if idx.size and idx.shape != (len(pts),):
        raise ShapeError(f"indices_n: expected shape ({len(pts)},), got {idx.shape}")
    return Region(points_n3=pts, scores_n=scores, indices_n=idx)


@dataclass(frozen=True)
class SupportTest:
    """How :func:`drop_support` recognises the surface a region stands on.

    A level of the region's upward-facing points (normal within ``acos(up_cos)`` of +z) is a
    *support* when it holds at least ``min_share`` of them and the map has upward-facing points
    at the same height (within ``tol``) in at least ``ring_cover`` of the ``cell``-sized columns
    that ring the region (up to ``ring`` cells outside it): the region has bled into a surface
    that goes on beyond it, such as the table under a mug or the floor under a chair.
    """

    cell: float = 0.02
    """Column size (m) of the ring test."""
    ring: int = 3
    """Ring width in cells around the region's columns."""
    level_bin: float = 0.002
    """Height bin (m) of the candidate levels."""
    tol: float = 0.002
    """Height tolerance (m) of a level: ring points within ``tol`` of it are on it."""
    above: float = 0.003
    """Region points less than this (m) above the support are dropped with it. Small, so that
    a thin object (a knife, a sheet of paper) is kept; and ``tol`` tight, so that its top is not
    taken for the surface it lies on."""
    min_share: float = 0.05
    """Smallest share of the region's upward-facing points that makes a candidate level."""
    ring_cover: float = 0.5
    """Share of the ring's columns that the surface must reach."""
    up_cos: float = 0.9
    """Cosine of the largest tilt of an upward-facing normal."""

    def __post_init__(self) -> None:
        for name in ("cell", "level_bin"):
            if not getattr(self, name) > 0:
                raise ValueError(f"SupportTest.{name}: expected a positive size in metres, got {getattr(self, name)!r}")
        for name in ("tol", "above"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"SupportTest.{name}: expected a height >= 0 in metres, got {getattr(self, name)!r}")
        if isinstance(self.ring, bool) or not isinstance(self.ring, (int, np.integer)) or self.ring < 1:
            raise ValueError(f"SupportTest.ring: expected a whole number of cells >= 1, got {self.ring!r}")
        for name in ("min_share", "ring_cover"):
            if not 0 < getattr(self, name) <= 1:
                raise ValueError(f"SupportTest.{name}: expected a share in (0, 1], got {getattr(self, name)!r}")
        if not -1 <= self.up_cos <= 1:
            raise ValueError(f"SupportTest.up_cos: expected a cosine in [-1, 1], got {self.up_cos!r}")


def drop_support(points_n3: np.ndarray, up_n: np.ndarray, region_idx: np.ndarray,
                 test: SupportTest = SupportTest()) -> tuple[np.ndarray, float | None]:
    """The region without the horizontal surface it stands on, when it has bled into one.

    Thresholded scores pick out an object together with a rim of the table (or floor, or shelf)
    around its base: features are fused per mask region, and a mask rarely stops at the exact
    edge. The lowest level of the region's upward-facing points that passes the ring test of
    ``test`` (see :class:`SupportTest`) is taken as the support; every region point less than
    ``test.above`` above it (or below it) is dropped. A region with no such level is returned
    whole (an object lying on nothing, or one whose base the map never saw).

    Args:
        points_n3: all map points.
        up_n: which map points face upwards (``normals[:, 2] >= test.up_cos``).
        region_idx: the region's map point indices.

    Returns:
        ``(kept_idx, support_z)``: the kept indices (a subset of ``region_idx``, same order) and
        the support's height (None when none was found).

    Shape:
        ``points_n3`` (N, 3), ``up_n`` (N,) bool, ``region_idx`` (R,) int -> (R',) int, float.
    """
    points_n3 = as_float_array("points_n3", np.asarray(points_n3), shape=(None, 3))
    up_n = as_array("up_n", np.asarray(up_n), shape=(len(points_n3),), kinds="b")
    idx = np.asarray(region_idx)
    if idx.size == 0:
        return np.zeros(0, np.int64), None
    idx = as_array("region_idx", idx, shape=(None,), kinds="iu").astype(np.int64)
    if idx.min() < 0 or idx.max() >= len(points_n3):
        raise IndexError(f"region_idx: expected map point indices in [0, {len(points_n3)}), "
                         f"got values from {idx.min()} to {idx.max()}")
    keep, z0 = support_mask(points_n3, up_n, np.flatnonzero(up_n), idx, test)
    return (idx if keep is None else idx[keep]), z0


def support_mask(points_n3: np.ndarray, up_n: np.ndarray, up_idx: np.ndarray, idx: np.ndarray,
                 test: SupportTest) -> tuple[np.ndarray | None, float | None]:
    """:func:`drop_support` on checked inputs, for callers that test many regions of one map:
    ``up_idx`` (the indices of ``up_n``'s true entries, increasing) is computed once per map, so
    a region's ring test looks only at the upward-facing points, not at every map point.

    Returns ``(keep, support_z)``: the mask over ``idx`` of the kept points (None: all kept, no
    support found) and the support's height.
    """
    from scipy import ndimage

    z_up = points_n3[idx[up_n[idx]], 2]
    if z_up.size < 10:
        return None, None
    bins = np.floor(z_up / test.level_bin).astype(np.int64)
    levels, counts = np.unique(bins, return_counts=True)
    levels = levels[counts >= max(5, test.min_share * z_up.size)]
    if levels.size == 0:
        return None, None
    # The region's columns, and the ring of columns around them, on a local grid.
    xy = points_n3[idx, :2]
    origin = np.floor(xy.min(axis=0) / test.cell).astype(np.int64) - test.ring
    cols = np.floor(xy / test.cell).astype(np.int64) - origin
    shape = tuple(cols.max(axis=0) + test.ring + 1)
    occupied = np.zeros(shape, bool)
    occupied[cols[:, 0], cols[:, 1]] = True
    size = 2 * test.ring + 1
    ring = ndimage.binary_dilation(occupied, structure=np.ones((size, size), bool)) & ~occupied
    n_ring = int(ring.sum())
    if n_ring == 0:
        return None, None
    # Upward-facing map points outside the region over the local grid.
    lo = (origin * test.cell).astype(np.float64)
    hi = lo + np.asarray(shape) * test.cell
    up_xy = points_n3[up_idx, :2]
    near = up_idx[np.all((up_xy >= lo) & (up_xy < hi), axis=1)]
    near = near[~np.isin(near, idx, assume_unique=True)]
    near_pts = points_n3[near]
    near_cols = np.floor(near_pts[:, :2] / test.cell).astype(np.int64) - origin
    inside = np.all((near_cols >= 0) & (near_cols < np.asarray(shape)), axis=1)
    near_pts, near_cols = near_pts[inside], near_cols[inside]
    for b in levels:  # lowest first
        in_bin = bins == b
        z0 = float(np.median(z_up[in_bin]))
        at = np.abs(near_pts[:, 2] - z0) < test.tol
        hit = np.zeros(shape, bool)
        hit[near_cols[at, 0], near_cols[at, 1]] = True
        if (hit & ring).sum() >= test.ring_cover * n_ring:
            return points_n3[idx, 2] > z0 + test.above, z0
    return None, None
