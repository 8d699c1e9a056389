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
    merging leak between objects. A boundary's mean sums its pixel edges in edge order, and
    the joined regions are numbered by their first region of the previous level.

    Shape:
        ``fine`` (n,) int, edges (E,) -> ``labels`` (L, n) int64, ``counts`` (L,) int64.
    """
    fine = np.asarray(fine, np.int64)
    cross = fine[src] != fine[dst]
    fa, fb, bw = fine[src[cross]], fine[dst[cross]], weight[cross].astype(np.float64)
    levels, counts = [fine], [int(count)]
    region = np.arange(int(count), dtype=np.int64)  # fine region -> region of the current level
    m = int(count)
    for t in thresholds:
        region, m = _merge_level(region, m, fa, fb, bw, float(t))
        levels.append(region[fine])
        counts.append(m)
    return np.stack(levels), np.asarray(counts, np.int64)


_HASH_MULTIPLIER = -7046029254386353131
"""0x9E3779B97F4A7C15 (Fibonacci hashing) as a signed 64-bit integer."""


@njit(cache=True, nogil=True)
def _pair_slots(codes, k):
    """Open-addressing table of the distinct values among ``codes[:k]`` (non-negative): the
    slot of each code and the table of keys (-1: empty). Shape: (k,) int64, (T,) int64."""
    size = 16
    while size < 2 * k:
        size *= 2
    keys = np.full(size, -1, np.int64)
    slot = np.empty(k, np.int64)
    mask = size - 1
    for e in range(k):
        c = codes[e]
        h = (c * _HASH_MULTIPLIER) & mask
        while keys[h] != -1 and keys[h] != c:
            h = (h + 1) & mask
        keys[h] = c
        slot[e] = h
    return slot, keys


@njit(cache=True, nogil=True)
def _merge_level(region, m, fa, fb, bw, t):
    """One level of :func:`merge_levels`: join adjacent regions while some boundary's mean
    weight is at most ``t``.

    Shape:
        ``region`` (m0,) int64 current region of each fine region, ``fa``, ``fb`` (B,) fine
        regions on the two sides of each cross edge, ``bw`` (B,) float64 -> the new
        ``region`` (m0,) and region count.
    """
    nb = fa.shape[0]
    codes = np.empty(nb, np.int64)
    eidx = np.empty(nb, np.int64)
    while True:
        k = 0
        for e in range(nb):
            a = region[fa[e]]
            b = region[fb[e]]
            if a != b:
                codes[k] = min(a, b) * m + max(a, b)
                eidx[k] = e
                k += 1
        if k == 0:
            break
        slot, keys = _pair_slots(codes, k)
        total = np.zeros(keys.shape[0])
        count = np.zeros(keys.shape[0], np.int64)
        for i in range(k):  # each boundary sums its edges in edge order
            total[slot[i]] += bw[eidx[i]]
            count[slot[i]] += 1
        parent = np.arange(m)
        joined = False
        for h in range(keys.shape[0]):
            if keys[h] >= 0 and total[h] / count[h] <= t:
                joined = True
                ra = _find(parent, keys[h] // m)
                rb = _find(parent, keys[h] % m)
                if ra != rb:
                    if ra < rb:
                        parent[rb] = ra
                    else:
                        parent[ra] = rb
        if not joined:
            break
        new_id = np.full(m, -1, np.int64)
        comp = np.empty(m, np.int64)
        n_comp = 0
        for i in range(m):  # components numbered by their first region, as scipy's connected_components does
            r = _find(parent, i)
            if new_id[r] < 0:
                new_id[r] = n_comp
                n_comp += 1
            comp[i] = new_id[r]
        for i in range(region.shape[0]):
            region[i] = comp[region[i]]
        m = n_comp
    return region, m


@dataclass(frozen=True)
class _RegionStats:
    """Per-region statistics of one level (all (m,) or (m, 3) float64)."""

    area: np.ndarray
    valid: np.ndarray
    inlier_frac: np.ndarray
    extent: np.ndarray
    mean: np.ndarray
    normal: np.ndarray


def _plane_stats(lab, m, p, valid, cfg: RGBDProposerConfig, n: int) -> _RegionStats:
    """Per-region area, valid-pixel count, plane fit, inlier fraction and extent (metres).

    A plane is fitted to each region's valid points (least squares from moments), refitted
    to the points within ``2 plane_tol_m`` of it, and the inlier fraction is the share of
    valid points within ``plane_tol_m`` of the refit. The extent is the full length of a
    uniform spread with the variance along the region's principal axis.

    Only regions that can be background planes are fitted (enough valid pixels and area for
    the extent, and large or wide enough for the refit); the others keep zeros there, which
    no rule of :func:`select_regions` reads.

    Shape:
        ``lab`` (n,) int, ``p`` (n, 3) with zeros where invalid, ``valid`` (n,).
    """
    tol = cfg.plane_tol_m
    lab = np.asarray(lab, np.int64)
    area = np.bincount(lab, minlength=m).astype(np.float64)
    mom = _moments(lab, m, p, valid)
    nv = mom[:, 0].copy()
    frac = area / n
    fit = (nv >= cfg.min_valid_fraction * area) & (frac >= cfg.min_area_fraction)
    mean, normal, eig = _planes_from_moments(mom, fit)
    extent = np.sqrt(12.0 * eig[:, 2])
    refit = fit & ((frac >= cfg.background_min_fraction) | (extent >= cfg.background_min_extent_m))
    if not refit.any():
        return _RegionStats(area, nv, np.zeros(m), extent, mean, normal)
    mean, normal, _ = _planes_from_moments(_near_moments(lab, m, p, valid, refit, mean, normal, 2.0 * tol), refit)
    inliers = _near_counts(lab, m, p, valid, refit, mean, normal, tol)
    inlier_frac = np.where(refit & (nv >= 3), inliers / np.maximum(nv, 1.0), 0.0)
    return _RegionStats(area, nv, inlier_frac, extent, mean, normal)


def _plane_distance_to(p, mean_3, normal_3):
    """Distance of every point from one plane. Shape: (n, 3) -> (n,)."""
    return np.abs((p - mean_3) @ normal_3)


def _pixels_on_plane(p, valid, mean_3, normal_3, tol):
    """``valid & (_plane_distance_to(p, mean_3, normal_3) <= tol)``, in one compiled pass.

    The matrix product's rounding is the BLAS library's own (its order of the three terms,
    fused multiply-adds or not); the compiled pass rounds its own way and knows how far
    apart two roundings can be. Only when some point lies that close to ``tol`` (about
    1e-17 m for points metres away) does the answer depend on it; the product is then taken
    as before.

    Shape:
        ``p`` (n, 3) float64, ``valid`` (n,) bool, (3,), (3,) -> (n,) bool.
    """
    on, ambiguous = _plane_pixels_kernel(p, valid, np.ascontiguousarray(mean_3, np.float64),
                                         np.ascontiguousarray(normal_3, np.float64), float(tol))
    if ambiguous:
        return valid & (_plane_distance_to(p, mean_3, normal_3) <= tol)
    return on


@njit(cache=True, nogil=True)
def _plane_pixels_kernel(p, valid, mean, normal, tol):
    """Points of ``valid`` within ``tol`` of the plane, and whether one lies within rounding
    distance of ``tol`` (twice the error bound of a three-term dot product, 2 * 3.4e-16 times
    the sum of the terms' magnitudes, rounded up to 1e-15)."""
    n = p.shape[0]
    on = np.zeros(n, np.bool_)
    for i in range(n):
        if not valid[i]:
            continue
        a = (p[i, 0] - mean[0]) * normal[0]
        b = (p[i, 1] - mean[1]) * normal[1]
        c = (p[i, 2] - mean[2]) * normal[2]
        d = abs((a + b) + c)
        if abs(d - tol) <= 1e-15 * (abs(a) + abs(b) + abs(c)):
            return on, True
        on[i] = d <= tol
    return on, False


@njit(cache=True, nogil=True, inline="always")
def _add_point(out, r, x, y, z):
    """Add one point to region ``r``'s count, sums and second-moment sums (row of ``out``)."""
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
        _add_point(out, r, x, y, z)
    return out


@njit(cache=True, nogil=True)
def _near_moments(lab, m, p, valid, which, mean, normal, lim):
    """:func:`_moments` of the valid points within ``lim`` of their region's plane (distance
    ``|(p - mean) . normal|``, summed x, y, z in that order), for the regions ``which``
    (zeros for the others).

    Shape:
        (n,), m, (n, 3), (n,), (m,) bool, (m, 3), (m, 3), float -> (m, 10).
    """
    out = np.zeros((m, 10))
    for i in range(lab.shape[0]):
        r = lab[i]
        if not (valid[i] and which[r]):
            continue
        x, y, z = p[i, 0], p[i, 1], p[i, 2]
        if not abs((x - mean[r, 0]) * normal[r, 0] + (y - mean[r, 1]) * normal[r, 1] + (z - mean[r, 2]) * normal[r, 2]) <= lim:
            continue
        _add_point(out, r, x, y, z)
    return out


@njit(cache=True, nogil=True)
def _near_counts(lab, m, p, valid, which, mean, normal, lim):
    """Per region of ``which``, the number of valid points within ``lim`` of its plane (the
    distance of :func:`_near_moments`; zeros for the other regions). Shape: (m,) float64."""
    out = np.zeros(m)
    for i in range(lab.shape[0]):
        r = lab[i]
        if not (valid[i] and which[r]):
            continue
        if abs((p[i, 0] - mean[r, 0]) * normal[r, 0] + (p[i, 1] - mean[r, 1]) * normal[r, 1]
               + (p[i, 2] - mean[r, 2]) * normal[r, 2]) <= lim:
            out[r] += 1.0
    return out


def _planes_from_moments(mom, which):
    """Least-squares plane of the regions ``which``: centroid (m, 3), unit normal (m, 3),
    covariance eigenvalues (m, 3) ascending; zeros for the other regions (each region's
    eigendecomposition is its own LAPACK call, so fitting a subset changes no value)."""
    m = mom.shape[0]
    mean, vec, eig = np.zeros((m, 3)), np.zeros((m, 3, 3)), np.zeros((m, 3))
    if not which.any():
        return mean, vec[:, :, 0], eig
    mo = mom[which]
    cnt = np.maximum(mo[:, 0], 1.0)
    mean[which] = mo[:, 1:4] / cnt[:, None]
    mu = mean[which]
    sxx, sxy, sxz, syy, syz, szz = (mo[:, 4 + i] / cnt for i in range(6))
    second = np.stack([sxx, sxy, sxz, sxy, syy, syz, sxz, syz, szz], axis=1).reshape(-1, 3, 3)
    cov = second - mu[:, :, None] * mu[:, None, :]
    e, v = np.linalg.eigh(cov)
    vec[which], eig[which] = v, np.clip(e, 0.0, None)
    return mean, vec[:, :, 0], eig


def select_regions(labels, counts, pts, valid, cfg: RGBDProposerConfig, h: int, w: int):
    """Filter the regions of every level and build the masks (the rules are described in
    :mod:`conceptfusion.perception.masks.rgbd`).

    Shape:
        ``labels`` (L, n) int, ``counts`` (L,), ``pts`` (n, 3) camera-frame points,
        ``valid`` (n,) bool -> ``masks_rhw`` (R, h, w) bool, ``level_r`` (R,) int64.
    """
    n = h * w
    p = np.where(valid[:, None], pts, 0.0).astype(np.float64)
    stats = [_plane_stats(labels[li], int(counts[li]), p, valid, cfg, n) for li in range(len(counts))]
    # Background planes first, over all levels. A pixel within tolerance of one is background,
    # wherever it lies: fragments of the floor cut off by the table still belong to the floor.
    plane_masks, plane_levels, planar = [], [], []
    plane_pixels: dict[bytes, np.ndarray] = {}
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
            # A region unchanged across levels has the same plane: its pixels are computed once.
            key = st.mean[r].tobytes() + st.normal[r].tobytes()
            on = plane_pixels.get(key)
            if on is None:
                on = plane_pixels[key] = _pixels_on_plane(p, valid, st.mean[r], st.normal[r], cfg.plane_tol_m)
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
    return _duplicates_kernel(np.asarray(lab_a, np.int64), np.asarray(area_a, np.float64), np.asarray(kept_a, np.bool_),
                              np.asarray(lab_b, np.int64), int(m_b), np.asarray(area_b, np.float64), float(iou_th))


@njit(cache=True, nogil=True)
def _duplicates_kernel(lab_a, area_a, kept_a, lab_b, m_b, area_b, iou_th):
    """:func:`_duplicates` on the pixels of kept regions of level a: intersection counts of
    (a, b) region pairs in a hash table."""
    n = lab_a.shape[0]
    codes = np.empty(n, np.int64)
    k = 0
    for i in range(n):
        a = lab_a[i]
        if kept_a[a]:
            codes[k] = a * m_b + lab_b[i]
            k += 1
    slot, keys = _pair_slots(codes, k)
    inter = np.zeros(keys.shape[0], np.int64)
    for i in range(k):
        inter[slot[i]] += 1
    dup = np.zeros(m_b, np.bool_)
    for h in range(keys.shape[0]):
        if keys[h] >= 0:
            ia, ib = keys[h] // m_b, keys[h] % m_b
            if inter[h] / (area_a[ia] + area_b[ib] - inter[h]) >= iou_th:
                dup[ib] = True
    return dup
