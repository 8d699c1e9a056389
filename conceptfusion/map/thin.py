"""Thinning a map to a point budget on a voxel grid, keeping every kept point exact.

A whole-apartment map (a few hundred thousand points, about 50 MB) is too large to keep beside
every episode recording; a copy with one point per voxel (the most confident one) shows the
same rooms and objects and answers queries with the kept points' own concept vectors. The
voxel is the smallest ``base_voxel * sqrt(2)**k`` whose occupied voxels fit the budget.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from conceptfusion.map.fusion import PointFusionMap

__all__ = ["Thinned", "voxel_representatives", "thin_map"]


@dataclass(frozen=True)
class Thinned:
    """A thinned copy of a map: the copy, the voxel edge used (metres; 0: nothing dropped) and
    the point count of the original."""

    map: PointFusionMap
    voxel: float
    original_points: int


def _cell_ids(pts: np.ndarray, voxel: float) -> np.ndarray:
    """One int64 per point naming its voxel on a grid from the cloud's corner, (N,)."""
    cells = np.floor((pts - pts.min(axis=0)) / voxel).astype(np.int64)
    span = cells.max(axis=0) + 1
    if float(span[0]) * float(span[1]) * float(span[2]) < 2.0**62:  # one integer per cell: a 1-D sort
        return (cells[:, 0] * span[1] + cells[:, 1]) * span[2] + cells[:, 2]
    return np.unique(cells, axis=0, return_inverse=True)[1].reshape(-1)  # a grid too fine for one key


def voxel_representatives(points_n3: np.ndarray, confidence_n: np.ndarray, voxel: float) -> np.ndarray:
    """Index of the most confident point in each occupied voxel (ties: the lowest index),
    sorted ascending.

    Shape:
        (N, 3), (N,) -> (V,) int64.
    """
    pts = np.asarray(points_n3, np.float64).reshape(-1, 3)
    conf = np.asarray(confidence_n, np.float64).reshape(-1)
    if len(pts) != len(conf):
        raise ValueError(f"points_n3, confidence_n: expected the same N, got {len(pts)} and {len(conf)}")
    if not voxel > 0:
        raise ValueError(f"voxel: expected a positive edge in metres, got {voxel}")
    if len(pts) == 0:
        return np.zeros(0, np.int64)
    cell_id = _cell_ids(pts, voxel)
    # most confident first, then lowest index, within each cell
    order = np.lexsort((np.arange(len(pts)), -conf, cell_id))
    sorted_cells = cell_id[order]
    first = np.ones(len(order), bool)
    first[1:] = sorted_cells[1:] != sorted_cells[:-1]
    return np.sort(order[first])


def thin_map(fmap: PointFusionMap, max_points: int, *, base_voxel: float = 0.01) -> Thinned:
    """``fmap`` itself when it holds at most ``max_points`` points, else one point per voxel
    (:func:`voxel_representatives`) on the finest grid of edge ``base_voxel * sqrt(2)**k``
    that leaves at most ``max_points``."""
    if max_points < 1:
        raise ValueError(f"max_points: expected at least 1, got {max_points}")
    n = len(fmap)
    if n <= max_points:
        return Thinned(fmap, 0.0, n)
    pts, conf = np.asarray(fmap.points, np.float64), fmap.confidence
    k = 0
    while True:  # count the occupied voxels (one per representative), pick them once it fits
        voxel = float(base_voxel) * 2.0 ** (k / 2)
        if len(np.unique(_cell_ids(pts, voxel))) <= max_points:
            return Thinned(fmap.subset(voxel_representatives(pts, conf, voxel)), voxel, n)
        k += 1
