"""Robust box geometry of point sets, shared by the spatial comparators.

Map regions carry stray points (depth noise, mis-fused features), so boxes are taken between
percentiles of the points rather than their raw minimum and maximum. World frame: z up,
metres.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import ConvexHull, QhullError, cKDTree

__all__ = [
    "check_trim",
    "check_nonneg",
    "robust_bounds",
    "oriented_extents",
    "footprint_overlap",
    "closest_points_distance",
    "MIN_FOOTPRINT",
]

MIN_FOOTPRINT = 1e-3
"""Metres: footprints thinner than this are padded to it."""


def check_trim(trim_pct: float) -> float:
    trim = float(trim_pct)
    if not 0.0 <= trim < 50.0:
        raise ValueError(f"trim_pct: expected a percentage in [0, 50), got {trim_pct!r}")
    return trim


def check_nonneg(name: str, value: float) -> float:
    v = float(value)
    if not (math.isfinite(v) and v >= 0.0):
        raise ValueError(f"{name}: expected a finite number >= 0, got {value!r}")
    return v


def robust_bounds(points_n3: np.ndarray, trim_pct: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Per-axis lower and upper bounds that ignore the ``trim_pct`` % most extreme points.

    Shape:
        ``points_n3`` (N, D) with N >= 1; returns two (D,) arrays.
    """
    trim = check_trim(trim_pct)
    pts = np.asarray(points_n3, dtype=np.float64)
    if trim == 0.0:
        return pts.min(axis=0), pts.max(axis=0)
    lo = np.percentile(pts, trim, axis=0, method="lower")
    hi = np.percentile(pts, 100.0 - trim, axis=0, method="higher")
    return lo, hi


def _yaw_candidates(xy_n2: np.ndarray) -> np.ndarray:
    """Edge directions of the 2D convex hull, folded into [0, pi/2) (plus 0)."""
    try:
        hull = ConvexHull(xy_n2)
    except (QhullError, ValueError):  # fewer than 3 points or all collinear
        return np.zeros(1)
    verts = xy_n2[hull.vertices]
    edges = np.roll(verts, -1, axis=0) - verts
    angles = np.mod(np.arctan2(edges[:, 1], edges[:, 0]), np.pi / 2)
    return np.unique(np.concatenate([[0.0], angles]))


def oriented_extents(points_n3: np.ndarray, trim_pct: float = 1.0) -> np.ndarray:
    """Extents of the smallest-footprint box with a vertical axis (yaw-only rotation).

    The yaw is the minimum-area rectangle of the footprint (rotating calipers over the convex
    hull edges of the xy points); the extents along that yaw and along z are then taken with
    :func:`robust_bounds`, and the world-axis box is kept when it is smaller after trimming.

    Shape:
        ``points_n3`` (N, 3); returns (3,) ``[extent_u, extent_v, extent_z]`` with u, v
        horizontal.
    """
    pts = np.asarray(points_n3, dtype=np.float64)
    xy = pts[:, :2]
    angles = _yaw_candidates(xy)
    c, s = np.cos(angles), np.sin(angles)
    # Hull vertices decide the yaw (cheap, exact for the untrimmed set) ...
    u = xy[:, :1] * c + xy[:, 1:] * s  # (N, K)
    v = -xy[:, :1] * s + xy[:, 1:] * c
    areas = (u.max(0) - u.min(0)) * (v.max(0) - v.min(0))
    best = float(angles[int(np.argmin(areas))])
    # ... and the extents at that yaw are trimmed like every other box.
    z_lo, z_hi = robust_bounds(pts[:, 2:], trim_pct)
    extents = []
    for yaw in (0.0, best):
        cy, sy = math.cos(yaw), math.sin(yaw)
        rot = np.stack([xy[:, 0] * cy + xy[:, 1] * sy, -xy[:, 0] * sy + xy[:, 1] * cy], axis=1)
        lo, hi = robust_bounds(rot, trim_pct)
        extents.append(hi - lo)
    uv = min(extents, key=lambda e: float(e[0] * e[1]))
    return np.array([uv[0], uv[1], float(z_hi[0] - z_lo[0])])


def _footprint(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """xy box padded to at least ``MIN_FOOTPRINT`` per side."""
    mid = (lo[:2] + hi[:2]) / 2.0
    half = np.maximum(hi[:2] - lo[:2], MIN_FOOTPRINT) / 2.0
    return mid - half, mid + half


def footprint_overlap(lo_a, hi_a, lo_b, hi_b) -> float:
    """Footprint intersection area over the smaller footprint area."""
    fa_lo, fa_hi = _footprint(lo_a, hi_a)
    fb_lo, fb_hi = _footprint(lo_b, hi_b)
    inter = np.clip(np.minimum(fa_hi, fb_hi) - np.maximum(fa_lo, fb_lo), 0.0, None)
    smaller = min(float(np.prod(fa_hi - fa_lo)), float(np.prod(fb_hi - fb_lo)))
    return float(np.prod(inter)) / smaller


def closest_points_distance(points_a_n3: np.ndarray, points_b_n3: np.ndarray, trim_pct: float) -> float:
    """Low percentile of the nearest-neighbour distances between two point sets, both ways.

    Shape:
        (N, 3), (M, 3) -> float.
    """
    d_ab, _ = cKDTree(points_b_n3).query(points_a_n3, k=1)
    d_ba, _ = cKDTree(points_a_n3).query(points_b_n3, k=1)
    d = np.concatenate([d_ab, d_ba])
    return float(np.percentile(d, trim_pct, method="lower")) if trim_pct > 0 else float(d.min())
