"""The default mask proposer: multi-scale graph segmentation of RGB-D frames.

Needs no weights. Every 4-neighbour pixel pair gets an edge weight that adds three cues,
each capped at ``max_term``:

* **colour**: CIELAB distance of the (lightly blurred) image, over ``color_scale``;
* **depth**: how far the step in inverse depth between the two pixels departs from the
  steps just before and after it, relative to the inverse depth. Inverse depth is affine
  in the pixel coordinates on any plane, so a slanted floor costs nothing while an
  occluding edge costs a lot; over ``depth_tol``;
* **normal**: ``1 - cos`` of the angle between the two surface normals, over
  ``1 - cos(normal_tol_deg)``. Concave creases (normals converging: where a box stands on
  a table) pay in full; convex ones (normals diverging: two faces of one box) pay only
  ``convex_weight`` of it, the local convexity cue of RGB-D object segmentation.

A pixel pair with one invalid depth gets the full geometric cost; two invalid pixels
only the colour cost. Graph-based segmentation (Felzenszwalb and Huttenlocher, 2004) then
merges regions along the sorted edges, once per scale ``k`` in ``scales``, each scale
continuing from the previous one. The levels are therefore nested: a box face at a fine
scale lies inside its box at a coarser one, so proposals overlap as SAM's do.

Regions are then filtered: too small, too large, mostly invalid depth, near-duplicates of
a region already proposed (IoU), and **background planes**: a region whose points fit a
plane (``plane_inlier_fraction`` of them within ``plane_tol_m``) and which covers at least ``background_min_fraction`` of the
frame or spans at least ``background_min_extent_m`` (floors, walls, table tops). Regions
lying mostly inside a background plane (its fragments at finer scales, or the plane with
an object at a coarser one) go too. With ``keep_background_planes=True`` each background
plane stays as exactly one mask instead, and its fragments still go.

Output order: by area, largest first; ties by scale, then by first pixel in raster order.
The result is a pure function of the inputs (no randomness, no threading).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import cv2
import numpy as np
from numba import njit
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from conceptfusion.cameras import backproject
from conceptfusion.masks import check_frame, empty_masks

__all__ = ["RGBDProposerConfig", "RGBDProposer"]

_REF_PIXELS = 240 * 320


@dataclass(frozen=True)
class RGBDProposerConfig:
    """Settings of :class:`RGBDProposer` (defaults tuned for 240x320 household scenes)."""

    fine_scale: float = 60.0
    """Graph-segmentation scale ``k`` of the finest level (larger: bigger regions), given
    for a 240x320 frame and scaled with the pixel count."""
    merge_thresholds: tuple[float, ...] = (2.0, 4.0, 7.0)
    """Mean boundary weight below which adjacent regions merge, one coarser level each,
    ascending."""
    lightness_weight: float = 0.5
    """Weight of CIELAB lightness against the two chroma axes in the colour cue (shading
    changes lightness far more than chroma)."""
    color_scale: float = 6.0
    """CIELAB distance that costs as much as one unit of edge weight."""
    depth_tol: float = 0.01
    """Relative inverse-depth step (beyond the local slope) that costs one unit."""
    normal_tol_deg: float = 20.0
    """Normal angle in degrees that costs one unit."""
    convex_weight: float = 0.15
    """Factor on the normal cost of convex creases (where faces of one object meet);
    concave creases (where an object rests on a support) pay in full."""
    max_term: float = 6.0
    """Cap of each cue's cost, so no single cue dominates the ordering of strong edges."""
    blur_sigma: float = 0.8
    """Gaussian blur of the image before the colour cue, in pixels (0: none)."""
    max_depth: float = math.inf
    """Depth beyond this (metres) counts as invalid."""
    min_area_fraction: float = 0.001
    """Smallest region, as a fraction of the frame's pixels; smaller regions are merged
    into a neighbour during segmentation and never proposed."""
    max_area_fraction: float = 0.6
    """Largest region proposed, as a fraction of the frame's pixels."""
    min_valid_fraction: float = 0.5
    """Regions with a smaller fraction of valid depth pixels are dropped."""
    plane_tol_m: float = 0.01
    """Distance (metres) from a region's fitted plane within which a point is an inlier."""
    plane_inlier_fraction: float = 0.9
    """A region is planar when at least this fraction of its valid points are inliers."""
    background_min_fraction: float = 0.2
    """A planar region covering at least this fraction of the frame is a background plane."""
    background_min_extent_m: float = 1.0
    """A planar region spanning at least this many metres is a background plane."""
    background_overlap: float = 0.8
    """A region with at least this fraction of its pixels on background planes is dropped."""
    keep_background_planes: bool = False
    """Keep each background plane as one mask (its fragments are dropped either way)."""
    dedupe_iou: float = 0.9
    """A region with at least this IoU with an already proposed one is dropped."""
    max_masks: int = 64
    """At most this many masks per frame (the largest are kept)."""

    def __post_init__(self) -> None:
        if any(not (t > 0) for t in self.merge_thresholds):
            raise ValueError(f"merge_thresholds: expected positive values, got {self.merge_thresholds}")
        if list(self.merge_thresholds) != sorted(self.merge_thresholds):
            raise ValueError(f"merge_thresholds: expected ascending values, got {self.merge_thresholds}")
        if self.lightness_weight < 0:
            raise ValueError(f"lightness_weight: expected >= 0, got {self.lightness_weight}")
        positive = ("fine_scale", "color_scale", "depth_tol", "normal_tol_deg", "max_term", "max_depth", "plane_tol_m",
                    "background_min_extent_m")
        for name in positive:
            if not getattr(self, name) > 0:
                raise ValueError(f"{name}: expected a positive value, got {getattr(self, name)}")
        if not 0 < self.normal_tol_deg < 180:
            raise ValueError(f"normal_tol_deg: expected a value in (0, 180), got {self.normal_tol_deg}")
        if self.blur_sigma < 0:
            raise ValueError(f"blur_sigma: expected >= 0, got {self.blur_sigma}")
        for f in fields(self):
            if f.name in ("min_area_fraction", "max_area_fraction", "min_valid_fraction", "background_min_fraction",
                          "background_overlap", "dedupe_iou", "plane_inlier_fraction"):
                v = getattr(self, f.name)
                if not 0 <= v <= 1:
                    raise ValueError(f"{f.name}: expected a fraction in [0, 1], got {v}")
        if self.min_area_fraction > self.max_area_fraction:
            raise ValueError(
                f"min_area_fraction, max_area_fraction: expected min <= max, got {self.min_area_fraction} > "
                f"{self.max_area_fraction}"
            )
        if self.max_masks < 1:
            raise ValueError(f"max_masks: expected at least 1, got {self.max_masks}")


class RGBDProposer:
    """Class-agnostic, overlapping masks from colour, depth and normal discontinuities.

    See the module docstring for the method. Deterministic; no weights.

    Args:
        config: settings (:class:`RGBDProposerConfig`); keyword overrides are applied on top.
    """

    privileged = False

    def __init__(self, config: RGBDProposerConfig | None = None, **overrides) -> None:
        base = config if config is not None else RGBDProposerConfig()
        if not isinstance(base, RGBDProposerConfig):
            raise TypeError(f"config: expected RGBDProposerConfig, got {type(base).__name__}")
        self.config = RGBDProposerConfig(**{**{f.name: getattr(base, f.name) for f in fields(base)}, **overrides})

    def propose(self, rgb_hw3, depth_hw, K_33) -> np.ndarray:
        """Masks of one frame (see :class:`conceptfusion.masks.MaskProposer`).

        Shape:
            ``rgb_hw3`` (H, W, 3) uint8, ``depth_hw`` (H, W) float, ``K_33`` (3, 3)
            -> ``masks_rhw`` (R, H, W) bool, R <= ``max_masks``.
        """
        masks, _ = self.segment(rgb_hw3, depth_hw, K_33)
        return masks

    def segment(self, rgb_hw3, depth_hw, K_33) -> tuple[np.ndarray, np.ndarray]:
        """Masks and the segmentation level (index into ``scales``) each came from.

        Shape:
            as :meth:`propose` -> ``masks_rhw`` (R, H, W) bool, ``level_r`` (R,) int64.
        """
        cfg = self.config
        rgb, depth, K = check_frame(rgb_hw3, depth_hw, K_33)
        h, w = depth.shape
        n = h * w
        with np.errstate(invalid="ignore"):
            depth = np.where(depth <= cfg.max_depth, depth, np.nan).astype(np.float32)
        valid = np.isfinite(depth)
        if not valid.any():
            return empty_masks(h, w), np.zeros(0, np.int64)
        vertex = backproject(depth, K)
        src, dst, weight = _edges(rgb, depth, vertex, _edge_aware_normals(vertex), valid, cfg)
        order = np.argsort(weight, kind="stable")
        k = cfg.fine_scale * (n / _REF_PIXELS)
        min_size = max(1, int(round(cfg.min_area_fraction * n)))
        fine, count = _felzenszwalb(src[order], dst[order], weight[order], n, k, min_size)
        labels, counts = _merge_levels(fine, count, src, dst, weight, cfg.merge_thresholds)
        return _select(labels, counts, vertex.reshape(n, 3), valid.reshape(n), cfg, h, w)


def _edges(rgb, depth, vertex, normals, valid, cfg: RGBDProposerConfig):
    """Right and down 4-neighbour edges with their combined weights.

    Shape:
        (H, W, 3), (H, W), vertex and normals (H, W, 3), (H, W) -> src (E,), dst (E,) int64,
        weight (E,) float32.
    """
    h, w = depth.shape
    img = rgb.astype(np.float32) / 255.0
    if cfg.blur_sigma > 0:
        img = cv2.GaussianBlur(img, (0, 0), cfg.blur_sigma)
    lab = cv2.cvtColor(img, cv2.COLOR_RGB2Lab)
    lab_weight = np.array([cfg.lightness_weight, 1.0, 1.0], np.float32)
    inv = np.where(valid, 1.0 / np.where(valid, depth, 1.0), np.nan).astype(np.float32)
    cos_tol = math.cos(math.radians(cfg.normal_tol_deg))
    idx = np.arange(h * w, dtype=np.int64).reshape(h, w)
    srcs, dsts, weights = [], [], []
    for axis in (1, 0):  # right neighbours, then down neighbours
        a = [slice(None), slice(None)]
        b = [slice(None), slice(None)]
        a[axis], b[axis] = slice(None, -1), slice(1, None)
        a, b = tuple(a), tuple(b)
        color = np.linalg.norm((lab[a] - lab[b]) * lab_weight, axis=-1) / cfg.color_scale
        depth_cost = _inverse_depth_jump(inv, axis) / cfg.depth_tol
        with np.errstate(invalid="ignore"):
            dot = np.sum(normals[a] * normals[b], axis=-1)
            convex = np.sum((normals[a] - normals[b]) * (vertex[a] - vertex[b]), axis=-1) > 0
        normal_cost = np.nan_to_num((1.0 - dot) / (1.0 - cos_tol), nan=0.0)
        normal_cost = np.where(convex, cfg.convex_weight * normal_cost, normal_cost)
        geo = np.minimum(np.nan_to_num(depth_cost, nan=0.0), cfg.max_term) + np.minimum(normal_cost, cfg.max_term)
        both = valid[a] & valid[b]
        one = valid[a] ^ valid[b]
        geo = np.where(both, geo, np.where(one, 2.0 * cfg.max_term, 0.0))
        weights.append((np.minimum(color, cfg.max_term) + geo).astype(np.float32).ravel())
        srcs.append(idx[a].ravel())
        dsts.append(idx[b].ravel())
    return np.concatenate(srcs), np.concatenate(dsts), np.concatenate(weights)


def _edge_aware_normals(vertex_hw3: np.ndarray) -> np.ndarray:
    """Unit normals from one-sided differences, each axis taking the side with the smaller
    depth change, so pixels next to an occluding edge keep their own surface's normal.

    Orientation is irrelevant here (only ``n_p . n_q`` and convexity use them, both
    invariant to flipping both normals; a consistent sign is kept by facing the camera).
    NaN where no valid neighbour exists on either side along an axis.

    Shape:
        (H, W, 3) -> (H, W, 3) float32.
    """
    v = vertex_hw3.astype(np.float32)
    tangents = []
    for axis in (1, 0):
        d = np.diff(v, axis=axis)
        pad = np.full_like(np.take(d, [0], axis=axis), np.nan)
        fwd = np.concatenate([d, pad], axis=axis)
        bwd = np.concatenate([pad, d], axis=axis)
        with np.errstate(invalid="ignore"):
            use_bwd = np.isnan(fwd[..., 2]) | (np.abs(bwd[..., 2]) < np.abs(fwd[..., 2]))
        tangents.append(np.where(use_bwd[..., None], bwd, fwd))
    n = np.cross(tangents[0], tangents[1])
    with np.errstate(invalid="ignore", divide="ignore"):
        n = n / np.linalg.norm(n, axis=-1, keepdims=True)
        flip = np.sum(n * v, axis=-1, keepdims=True) > 0
    return np.where(flip, -n, n).astype(np.float32)


def _inverse_depth_jump(inv_hw: np.ndarray, axis: int) -> np.ndarray:
    """Relative departure of each neighbour step of inverse depth from the adjacent steps.

    For pixels ``p``, ``q`` along ``axis`` with steps ``s_prev`` (into ``p``), ``s`` (p to
    q) and ``s_next`` (out of ``q``): ``min(|s - s_prev|, |s - s_next|) / mean(inv_p,
    inv_q)``, using whichever adjacent steps exist (``|s|`` when neither does). Zero on
    any plane, large at occluding edges. NaN where ``p`` or ``q`` is invalid.

    Shape:
        (H, W) -> (H, W-1) for axis 1, (H-1, W) for axis 0.
    """
    x = inv_hw if axis == 1 else inv_hw.T
    s = np.diff(x, axis=1)  # (H, W-1)
    pad = np.full((x.shape[0], 1), np.nan, x.dtype)
    prev = np.concatenate([pad, s[:, :-1]], axis=1)
    nxt = np.concatenate([s[:, 1:], pad], axis=1)
    with np.errstate(invalid="ignore"):
        dev = np.fmin(np.abs(s - prev), np.abs(s - nxt))
        dev = np.where(np.isnan(prev) & np.isnan(nxt), np.abs(s), dev)
        rel = dev / (0.5 * (x[:, :-1] + x[:, 1:]))
    return rel if axis == 1 else rel.T


@njit(cache=True, nogil=True, inline="always")
def _find(parent, a):
    root = a
    while parent[root] != root:
        root = parent[root]
    while parent[a] != root:
        nxt = parent[a]
        parent[a] = root
        a = nxt
    return root


@njit(cache=True, nogil=True, inline="always")
def _union(parent, size, internal, a, b, wgt):
    if size[a] < size[b] or (size[a] == size[b] and b < a):
        a, b = b, a
    parent[b] = a
    size[a] += size[b]
    internal[a] = max(internal[a], internal[b], wgt)


@njit(cache=True, nogil=True)
def _felzenszwalb(src, dst, weight, n, k, min_size):
    """Graph-based segmentation (Felzenszwalb and Huttenlocher, 2004).

    Edges must come sorted by weight. Two regions merge along an edge when its weight is
    at most ``min(int_a + k/|a|, int_b + k/|b|)`` (``int``: the largest weight merged into
    the region so far); then regions smaller than ``min_size`` merge into the neighbour
    across their lightest edge. Labels are numbered by first pixel in raster order.

    Returns ``labels`` (n,) int64 and the number of regions.
    """
    parent = np.arange(n)
    size = np.ones(n, np.int64)
    internal = np.zeros(n, np.float64)
    for e in range(src.shape[0]):
        a = _find(parent, src[e])
        b = _find(parent, dst[e])
        if a == b:
            continue
        wgt = weight[e]
        if wgt <= internal[a] + k / size[a] and wgt <= internal[b] + k / size[b]:
            _union(parent, size, internal, a, b, wgt)
    for e in range(src.shape[0]):
        a = _find(parent, src[e])
        b = _find(parent, dst[e])
        if a != b and (size[a] < min_size or size[b] < min_size):
            _union(parent, size, internal, a, b, weight[e])
    labels = np.empty(n, np.int64)
    root_id = np.full(n, -1, np.int64)
    count = 0
    for p in range(n):
        r = _find(parent, p)
        if root_id[r] < 0:
            root_id[r] = count
            count += 1
        labels[p] = root_id[r]
    return labels, count


def _merge_levels(fine, count, src, dst, weight, thresholds):
    """Coarser levels by merging adjacent regions whose mean boundary weight is low.

    Level 0 is ``fine``. For each threshold, adjacent regions whose boundary edges have a
    mean weight at most the threshold are joined (connected components of such pairs),
    repeatedly until no pair qualifies; the result is the next level. Levels are nested.
    A mean over the whole boundary is robust to the few weak edges that let pixel-level
    merging leak between objects.

    Shape:
        ``fine`` (n,) int, edges (E,) -> ``labels`` (L, n) int64, ``counts`` (L,) int64.
    """
    cross = fine[src] != fine[dst]
    bs, bd, bw = src[cross], dst[cross], weight[cross].astype(np.float64)
    levels, counts = [fine], [count]
    lab, m = fine, count
    for t in thresholds:
        while True:
            a, b = lab[bs], lab[bd]
            keep = a != b
            lo, hi = np.minimum(a, b)[keep], np.maximum(a, b)[keep]
            if len(lo) == 0:
                break
            pairs, inv = np.unique(lo * m + hi, return_inverse=True)
            mean = np.bincount(inv, weights=bw[keep]) / np.bincount(inv)
            join = mean <= t
            if not join.any():
                break
            graph = coo_matrix((np.ones(int(join.sum())), (pairs[join] // m, pairs[join] % m)), shape=(m, m))
            m, comp = connected_components(graph, directed=False)
            lab = comp.astype(np.int64)[lab]
        levels.append(lab)
        counts.append(m)
    return np.stack(levels), np.asarray(counts, np.int64)


def _plane_stats(lab, m, pts, valid, tol):
    """Per-region area, valid-pixel count, plane inlier fraction and extent (metres).

    A plane is fitted to each region's valid points (least squares from moments), refitted
    to the points within ``2 tol`` of it, and the inlier fraction is the share of valid
    points within ``tol`` of the refit. The extent is the full length of a uniform spread
    with the variance along the region's principal axis.

    Shape:
        ``lab`` (n,) int, ``pts`` (n, 3), ``valid`` (n,) -> four (m,) float64 arrays.
    """
    area = np.bincount(lab, minlength=m).astype(np.float64)
    p = np.where(valid[:, None], pts, 0.0).astype(np.float64)
    mom = _moments(lab, m, p, valid)
    nv = mom[:, 0].copy()
    mean, normal, eig = _planes_from_moments(mom)
    extent = np.sqrt(12.0 * eig[:, 2])
    near = valid & (_plane_distance(lab, p, mean, normal) <= 2.0 * tol)
    mean, normal, _ = _planes_from_moments(_moments(lab, m, p, near))
    inlier = valid & (_plane_distance(lab, p, mean, normal) <= tol)
    inliers = np.bincount(lab, weights=inlier.astype(np.float64), minlength=m)
    inlier_frac = np.where(nv >= 3, inliers / np.maximum(nv, 1.0), 0.0)
    return area, nv, inlier_frac, extent


@njit(cache=True, nogil=True)
def _moments(lab, m, p, use):
    """Per-region count, sums and second-moment sums of the points with ``use`` set.

    Shape:
        (n,), (n, 3), (n,) -> (m, 10): count, sum x, y, z, sum xx, xy, xz, yy, yz, zz.
    """
    out = np.zeros((m, 10))
    for i in range(lab.shape[0]):
        if not use[i]:
            continue
        r = lab[i]
        x, y, z = p[i, 0], p[i, 1], p[i, 2]
        out[r, 0] += 1.0
        out[r, 1] += x
        out[r, 2] += y
        out[r, 3] += z
        out[r, 4] += x * x
        out[r, 5] += x * y
        out[r, 6] += x * z
        out[r, 7] += y * y
        out[r, 8] += y * z
        out[r, 9] += z * z
    return out


@njit(cache=True, nogil=True)
def _plane_distance(lab, p, mean, normal):
    """Distance of each point from its region's plane. Shape: (n,) float64."""
    out = np.empty(lab.shape[0])
    for i in range(lab.shape[0]):
        r = lab[i]
        out[i] = abs(
            (p[i, 0] - mean[r, 0]) * normal[r, 0] + (p[i, 1] - mean[r, 1]) * normal[r, 1] + (p[i, 2] - mean[r, 2]) * normal[r, 2]
        )
    return out


def _planes_from_moments(mom):
    """Least-squares plane per region: centroid (m, 3), unit normal (m, 3), covariance
    eigenvalues (m, 3) ascending."""
    cnt = np.maximum(mom[:, 0], 1.0)
    mean = mom[:, 1:4] / cnt[:, None]
    sxx, sxy, sxz, syy, syz, szz = (mom[:, 4 + i] / cnt for i in range(6))
    second = np.stack([sxx, sxy, sxz, sxy, syy, syz, sxz, syz, szz], axis=1).reshape(-1, 3, 3)
    cov = second - mean[:, :, None] * mean[:, None, :]
    eig, vec = np.linalg.eigh(cov)
    return mean, vec[:, :, 0], np.clip(eig, 0.0, None)


def _select(labels, counts, pts, valid, cfg: RGBDProposerConfig, h: int, w: int):
    """Filter the regions of every level and build the masks (see the module docstring)."""
    n = h * w
    stats = [_plane_stats(labels[li], int(counts[li]), pts, valid, cfg.plane_tol_m) for li in range(len(counts))]
    # Background planes first, over all levels: their pixels decide which regions are fragments.
    background_px = np.zeros(n, bool)
    planes = []
    for li, (area, nv, inlier_frac, extent) in enumerate(stats):
        frac = area / n
        is_plane = (
            (nv >= cfg.min_valid_fraction * area)
            & (inlier_frac >= cfg.plane_inlier_fraction)
            & ((frac >= cfg.background_min_fraction) | (extent >= cfg.background_min_extent_m))
            & (frac >= cfg.min_area_fraction)
        )
        planes.append(is_plane)
        if is_plane.any():
            background_px |= is_plane[labels[li]]
    kept: list[tuple[int, int]] = []  # (level, label)
    kept_by_level: list[np.ndarray] = []
    for li, (area, nv, _, _) in enumerate(stats):
        m = int(counts[li])
        lab = labels[li]
        on_bg = np.bincount(lab, weights=background_px.astype(np.float64), minlength=m) / np.maximum(area, 1.0)
        ok = (
            (area >= cfg.min_area_fraction * n)
            & (area <= cfg.max_area_fraction * n)
            & (nv >= cfg.min_valid_fraction * area)
        )
        ordinary = ok & ~planes[li] & (on_bg < cfg.background_overlap)
        keep = ordinary | (ok & planes[li] & cfg.keep_background_planes)
        for lj, kept_j in enumerate(kept_by_level):
            if kept_j.any() and keep.any():
                keep &= ~_duplicates(labels[lj], int(counts[lj]), stats[lj][0], kept_j, lab, m, area, cfg.dedupe_iou)
        kept_by_level.append(keep)
        kept.extend((li, int(r)) for r in np.flatnonzero(keep))
    if not kept:
        return empty_masks(h, w), np.zeros(0, np.int64)
    areas = np.array([stats[li][0][r] for li, r in kept])
    order = sorted(range(len(kept)), key=lambda i: (-areas[i], kept[i][0], kept[i][1]))[: cfg.max_masks]
    masks = np.empty((len(order), h, w), bool)
    level = np.empty(len(order), np.int64)
    for out, i in enumerate(order):
        li, r = kept[i]
        masks[out] = (labels[li] == r).reshape(h, w)
        level[out] = li
    return masks, level


def _duplicates(lab_a, m_a, area_a, kept_a, lab_b, m_b, area_b, iou_th):
    """Regions of level b whose IoU with a kept region of level a is at least ``iou_th``.

    Shape:
        labels (n,), counts, areas (m_a,), (m_b,), kept (m_a,) bool -> (m_b,) bool.
    """
    codes = lab_a.astype(np.int64) * m_b + lab_b
    pairs, inter = np.unique(codes, return_counts=True)
    ia, ib = pairs // m_b, pairs % m_b
    iou = inter / (area_a[ia] + area_b[ib] - inter)
    hit = kept_a[ia] & (iou >= iou_th)
    dup = np.zeros(m_b, bool)
    dup[ib[hit]] = True
    return dup
