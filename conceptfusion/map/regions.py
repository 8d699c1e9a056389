"""3D regions of a map: the answer to "where is X?".

A :class:`Region` is a spatially connected set of map points that a query selected. It is a
plain container: the spatial comparators, the agents and the evaluation code read its
geometry and never need the map it came from.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from conceptfusion._checks import as_float_array
from conceptfusion.errors import ShapeError

__all__ = ["Region", "region_from_points"]


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
