"""Graph to regions to masks: the segmentation half of :mod:`conceptfusion.perception.masks.rgbd`.

:func:`felzenszwalb` over-segments a weighted pixel graph, :func:`merge_levels` builds
nested coarser levels by merging regions with weak boundaries, and :func:`select_regions`
fits planes to every region, finds background planes and keeps the regions worth
proposing. The pixel graph's weights come from :mod:`conceptfusion.perception.masks.rgbd`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from conceptfusion.perception.masks.base import empty_masks
from conceptfusion.perception.masks.rgbd_config import RGBDProposerConfig

__all__ = ["felzenszwalb", "merge_levels", "select_regions"]


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
def felzenszwalb(src, dst, weight, n, k, min_size):
    """Graph-based segmentation (Felzenszwalb and Huttenlocher, 2004).

    Edges must come sorted by weight. Two regions merge along an edge when its weight is
    at most ``min(int_a + k/|a|, int_b + k/|b|)`` (``int``: the largest weight merged into
    the region so far); then regions smaller than ``min_size`` merge into the neighbour
    across their lightest edge. Labels are numbered by first pixel in raster order.

    Shape:
        ``src``, ``dst`` (E,) int pixel indices, ``weight`` (E,) sorted ascending ->
        ``labels`` (n,) int64 and the number of regions.
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


def merge_levels(fine, count, src, dst, weight, thresholds):
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


@dataclass(frozen=True)
class _RegionStats:
    """Per-region statistics of one level (all (m,) or (m, 3) float64)."""

    area: np.ndarray
    valid: np.ndarray
    inlier_frac: np.ndarray
    extent: np.ndarray
    mean: np.ndarray
    normal: np.ndarray


def _plane_stats(lab, m, p, valid, tol) -> _RegionStats:
    """Per-region area, valid-pixel count, plane fit, inlier fraction and extent (metres).

    A plane is fitted to each region's valid points (least squares from moments), refitted
    to the points within ``2 tol`` of it, and the inlier fraction is the share of valid
    points within ``tol`` of the refit. The extent is the full length of a uniform spread
    with the variance along the region's principal axis.

    Shape:
        ``lab`` (n,) int, ``p`` (n, 3) with zeros where invalid, ``valid`` (n,).
    """
    area = np.bincount(lab, minlength=m).astype(np.float64)
    mom = _moments(lab, m, p, valid)
    nv = mom[:, 0].copy()
    mean, normal, eig = _planes_from_moments(mom)
    extent = np.sqrt(12.0 * eig[:, 2])
    near = valid & (_plane_distance(lab, p, mean, normal) <= 2.0 * tol)
    mean, normal, _ = _planes_from_moments(_moments(lab, m, p, near))
    inlier = valid & (_plane_distance(lab, p, mean, normal) <= tol)
    inliers = np.bincount(lab, weights=inlier.astype(np.float64), minlength=m)
    inlier_frac = np.where(nv >= 3, inliers / np.maximum(nv, 1.0), 0.0)
    return _RegionStats(area, nv, inlier_frac, extent, mean, normal)


def _plane_distance_to(p, mean_3, normal_3):
    """Distance of every point from one plane. Shape: (n, 3) -> (n,)."""
    return np.abs((p - mean_3) @ normal_3)


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


def select_regions(labels, counts, pts, valid, cfg: RGBDProposerConfig, h: int, w: int):
    """Filter the regions of every level and build the masks (the rules are described in
    :mod:`conceptfusion.perception.masks.rgbd`).

    Shape:
        ``labels`` (L, n) int, ``counts`` (L,), ``pts`` (n, 3) camera-frame points,
        ``valid`` (n,) bool -> ``masks_rhw`` (R, h, w) bool, ``level_r`` (R,) int64.
    """
    n = h * w
    p = np.where(valid[:, None], pts, 0.0).astype(np.float64)
    stats = [_plane_stats(labels[li], int(counts[li]), p, valid, cfg.plane_tol_m) for li in range(len(counts))]
    # Background planes first, over all levels. A pixel within tolerance of one is background,
    # wherever it lies: fragments of the floor cut off by the table still belong to the floor.
    plane_masks, plane_levels, planar = [], [], []
    for li, st in enumerate(stats):
        frac = st.area / n
        is_plane = (
            (st.valid >= cfg.min_valid_fraction * st.area)
            & (st.inlier_frac >= cfg.plane_inlier_fraction)
            & ((frac >= cfg.background_min_fraction) | (st.extent >= cfg.background_min_extent_m))
            & (frac >= cfg.min_area_fraction)
        )
        planar.append(is_plane)
        for r in np.flatnonzero(is_plane):
            on = valid & (_plane_distance_to(p, st.mean[r], st.normal[r]) <= cfg.plane_tol_m)
            if not any(_iou(on, q) >= cfg.dedupe_iou for q in plane_masks):
                plane_masks.append(on)
                plane_levels.append(li)
    background_px = np.logical_or.reduce(plane_masks) if plane_masks else np.zeros(n, bool)
    # Candidates: (area, level, tie-break, mask builder).
    candidates = []
    kept_by_level: list[np.ndarray] = []
    for li, st in enumerate(stats):
        m = int(counts[li])
        lab = labels[li]
        on_bg = np.bincount(lab, weights=background_px.astype(np.float64), minlength=m) / np.maximum(st.area, 1.0)
        keep = (
            (st.area >= cfg.min_area_fraction * n)
            & (st.area <= cfg.max_area_fraction * n)
            & (st.valid >= cfg.min_valid_fraction * st.area)
            & ~planar[li]
            & (on_bg < cfg.background_overlap)
        )
        for lj, kept_j in enumerate(kept_by_level):
            if kept_j.any() and keep.any():
                keep &= ~_duplicates(labels[lj], int(counts[lj]), stats[lj].area, kept_j, lab, m, st.area, cfg.dedupe_iou)
        kept_by_level.append(keep)
        candidates.extend((st.area[r], li, int(r), lab, int(r)) for r in np.flatnonzero(keep))
    if cfg.keep_background_planes:
        for k, (on, li) in enumerate(zip(plane_masks, plane_levels)):
            area = float(on.sum())
            if area >= cfg.min_area_fraction * n:  # a kept plane may fill the frame
                candidates.append((area, li, -1 - k, on, None))
    if not candidates:
        return empty_masks(h, w), np.zeros(0, np.int64)
    candidates.sort(key=lambda c: (-c[0], c[1], c[2]))
    chosen = candidates[: cfg.max_masks]
    masks = np.empty((len(chosen), h, w), bool)
    level = np.empty(len(chosen), np.int64)
    for out, (_, li, _, src, r) in enumerate(chosen):
        masks[out] = (src == r).reshape(h, w) if r is not None else src.reshape(h, w)
        level[out] = li
    return masks, level


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    union = np.count_nonzero(a | b)
    return np.count_nonzero(a & b) / union if union else 0.0


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
