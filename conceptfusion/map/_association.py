"""Projective data association, compiled (numba) and split over threads.

For each map point, project into the new frame; if it lands on a valid pixel ``j`` within
``sqrt(dist_th2)`` of that pixel's vertex with normals agreeing (``dot >= cos_th``), it is a
candidate for ``j``. Per pixel the candidate with the highest confidence wins, ties to the
nearest, then to the lowest point index. A valid pixel with no candidate is *covered* when
the nearest point projecting onto one of its 8 neighbours passes the same tests.

The points are scanned in ranges (:func:`scan`), on several threads for large maps, and the
partial results merged (:func:`merge_scans`) so that the outcome is exactly that of one scan
in point order: a range's best candidate replaces the earlier ranges' only if strictly
better, and the nearest-point bookkeeping, which keeps depths rounded to float32, is merged
by the exact minimum depth each range saw (see :func:`merge_scans`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from conceptfusion.map._threads import balanced_bounds, map_bounds

__all__ = ["associate"]

_PROJECT_BLOCK = 2048
_THREAD_CHUNK = 1 << 16  # fewest points per thread
_COVER_CHUNK = 1 << 13  # fewest pixels per thread in the coverage check
_COST_STRIDE = 64
"""Points per sample of :func:`view_cost` (the split of the scan between threads)."""
_IN_VIEW_COST = 6.0
"""Scan work of a point that projects into the frame against one that does not (measured on
the bench orbit: about 4 ns to project a point, 24 ns more for the tests of one in view)."""


def associate(geo, n, world_to_cam, K, valid_pix, obs, dist_th2, cos_th, h, w):
    """Match the first ``n`` map points (rows of ``geo``: position 0:3, normal 3:6, confidence
    9) with the frame's valid pixels (flat pixel ``valid_pix[j]``, vertex ``obs[j, 0:3]``,
    normal ``obs[j, 3:6]``; ``obs`` is read in place, any further columns ignored).

    Returns ``(points, pixels, covered)``: matched map point indices and valid-pixel indices,
    (M,) int64 in increasing point order (a point wins at most one pixel, a pixel at most one
    point), and (V,) bool over the valid pixels.

    The point ranges the threads scan are split by estimated work (:func:`view_cost`: a point
    in view costs several times one outside), and the coverage check by unmatched pixels, the
    only ones it works on; any split gives the same result.
    """
    pixel_to_valid = pixel_index(valid_pix, h, w)
    bounds = balanced_bounds(n, view_cost(geo, n, world_to_cam, K, h, w), _COST_STRIDE, min_chunk=_THREAD_CHUNK)
    parts = map_bounds(
        lambda start, stop: scan(
            geo, start, stop, world_to_cam, K, pixel_to_valid, obs, dist_th2, cos_th, h, w, start > 0
        ),
        bounds,
    )
    acc = parts[0]
    for part in parts[1:]:
        merge_scans(*acc, *part)
    best_pt, _, _, near_pt, _, _ = acc
    covered = np.zeros(obs.shape[0], np.bool_)
    unmatched_cum = np.concatenate(([0], np.cumsum(best_pt < 0)))
    map_bounds(  # each pixel's flag on its own: any split gives the same flags
        lambda start, stop: cover(geo, best_pt, near_pt, valid_pix, obs, dist_th2, cos_th, h, w, start, stop, covered),
        balanced_bounds(obs.shape[0], unmatched_cum, 1, min_chunk=_COVER_CHUNK),
    )
    pts, pixels = matches_in_point_order(n, best_pt)
    return pts, pixels, covered


@njit(cache=True, nogil=True, error_model="numpy")
def view_cost(geo, n, world_to_cam, K, h, w):
    """Estimated scan work of the first ``n`` points, sampled every :data:`_COST_STRIDE`:
    ``out[i]`` is the cost of points ``[0, i * stride)`` (the last entry: all ``n``), a point
    counting 1 outside the frame and :data:`_IN_VIEW_COST` when it projects into it (as
    :func:`_project_block` decides for the scan).

    Shape:
        returns (ceil(n / stride) + 1,) float64.
    """
    m = (n + _COST_STRIDE - 1) // _COST_STRIDE
    out = np.zeros(m + 1, np.float64)
    xs, ys, zs, zcs = np.empty(1), np.empty(1), np.empty(1), np.empty(1)
    qs = np.empty(1, np.int32)
    acc = 0.0
    for i in range(m):
        k = i * _COST_STRIDE
        _project_block(geo, k, 1, world_to_cam, K, h, w, xs, ys, zs, qs, zcs)
        cost = _IN_VIEW_COST if qs[0] >= 0 else 1.0
        acc += cost * min(_COST_STRIDE, n - k)
        out[i + 1] = acc
    return out


@njit(cache=True, nogil=True)
def pixel_index(valid_pix, h, w):
    """Valid-pixel number of each flat pixel (-1: not valid), (h * w,) int32."""
    out = np.full(h * w, -1, np.int32)
    for j in range(valid_pix.shape[0]):
        out[valid_pix[j]] = j
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def _project_block(geo, start, cnt, world_to_cam, K, h, w, xs, ys, zs, qs, zcs):
    """Project points ``start:start + cnt``: flat pixel ``v * w + u`` (``u, v`` the rounded
    projection; -1 outside the frame or behind the camera) into ``qs`` and camera depth into
    ``zcs``. Positions are first copied into contiguous buffers so that the projection runs
    branch-free over SIMD lanes; the arithmetic, and so every rounding, is that of a plain
    per-point loop."""
    r00, r01, r02, t0 = world_to_cam[0, 0], world_to_cam[0, 1], world_to_cam[0, 2], world_to_cam[0, 3]
    r10, r11, r12, t1 = world_to_cam[1, 0], world_to_cam[1, 1], world_to_cam[1, 2], world_to_cam[1, 3]
    r20, r21, r22, t2 = world_to_cam[2, 0], world_to_cam[2, 1], world_to_cam[2, 2], world_to_cam[2, 3]
    fx, s, cx, fy, cy = K[0, 0], K[0, 1], K[0, 2], K[1, 1], K[1, 2]
    fw = np.float64(w)
    fh = np.float64(h)
    for i in range(cnt):
        xs[i] = geo[start + i, 0]
        ys[i] = geo[start + i, 1]
        zs[i] = geo[start + i, 2]
    for i in range(cnt):
        x = xs[i]
        y = ys[i]
        z = zs[i]
        zc = r20 * x + r21 * y + r22 * z + t2
        xc = (r00 * x + r01 * y + r02 * z + t0) / zc
        yc = (r10 * x + r11 * y + r12 * z + t1) / zc
        u = np.rint(fx * xc + s * yc + cx)
        v = np.rint(fy * yc + cy)
        inside = (zc > 0.0) & (u >= 0.0) & (u < fw) & (v >= 0.0) & (v < fh)
        q = np.int32(min(max(v, 0.0), fh)) * np.int32(w) + np.int32(min(max(u, 0.0), fw))
        qs[i] = q if inside else -1
        zcs[i] = zc


@njit(cache=True, nogil=True, inline="always")
def _match_d2(geo, k, obs, j, dist_th2, cos_th):
    """The squared distance between map point ``k`` and frame vertex ``j`` (``obs[j, 0:3]``)
    when they are within the distance and angle thresholds, else -1."""
    dx = geo[k, 0] - obs[j, 0]
    dy = geo[k, 1] - obs[j, 1]
    dz = geo[k, 2] - obs[j, 2]
    d2 = dx * dx + dy * dy + dz * dz
    if d2 >= dist_th2:
        return -1.0
    if not geo[k, 3] * obs[j, 3] + geo[k, 4] * obs[j, 4] + geo[k, 5] * obs[j, 5] >= cos_th:
        return -1.0
    return d2


@njit(cache=True, nogil=True)
def scan(geo, start, stop, world_to_cam, K, pixel_to_valid, obs, dist_th2, cos_th, h, w, track_min):
    """Candidates among points ``start:stop``, in point order.

    Returns ``(best_pt, best_conf, best_d2, near_pt, near_z, near_min)``: per valid pixel the
    winning candidate (-1: none), its confidence and squared distance, (V,); per pixel the
    nearest point projecting onto it (-1: none), its depth as kept (float32), and, when
    ``track_min`` (a later range, to be merged), the exact smallest depth seen (float64),
    (h * w,) (else empty).
    """
    num_valid = obs.shape[0]
    best_pt = np.full(num_valid, -1, np.int32)
    best_conf = np.zeros(num_valid, np.float32)
    best_d2 = np.zeros(num_valid, np.float32)
    near_pt = np.full(h * w, -1, np.int32)
    near_z = np.full(h * w, np.inf, np.float32)
    near_min = np.full(h * w if track_min else 0, np.inf, np.float64)
    xs = np.empty(_PROJECT_BLOCK, np.float64)
    ys = np.empty(_PROJECT_BLOCK, np.float64)
    zs = np.empty(_PROJECT_BLOCK, np.float64)
    qs = np.empty(_PROJECT_BLOCK, np.int32)
    zcs = np.empty(_PROJECT_BLOCK, np.float64)
    for block in range(start, stop, _PROJECT_BLOCK):
        cnt = min(_PROJECT_BLOCK, stop - block)
        _project_block(geo, block, cnt, world_to_cam, K, h, w, xs, ys, zs, qs, zcs)
        for i in range(cnt):
            q = qs[i]
            if q < 0:
                continue
            k = block + i
            z = zcs[i]
            if z < near_z[q]:
                near_z[q] = z
                near_pt[q] = k
            if track_min and z < near_min[q]:
                near_min[q] = z
            j = pixel_to_valid[q]
            if j < 0:
                continue
            d2 = _match_d2(geo, k, obs, j, dist_th2, cos_th)
            if d2 < 0.0:
                continue
            c = geo[k, 9]
            if best_pt[j] < 0 or c > best_conf[j] or (c == best_conf[j] and d2 < best_d2[j]):
                best_pt[j] = k
                best_conf[j] = c
                best_d2[j] = d2
    return best_pt, best_conf, best_d2, near_pt, near_z, near_min


@njit(cache=True, nogil=True)
def merge_scans(best_pt, best_conf, best_d2, near_pt, near_z, near_min,
                b_pt, b_conf, b_d2, b_near_pt, b_near_z, b_near_min):
    """Fold the scan of a later range (``b_*``) into an earlier one, in place.

    A later candidate wins only when strictly better (higher confidence, or equal and
    nearer), as in one scan. The nearest point: one scan keeps ``near_z`` rounded to float32
    and replaces it only by a strictly smaller exact depth; if the later range saw a depth
    below the earlier range's kept one, its first such point would have replaced it, and from
    there on the single scan would have followed the later range's own record, so the later
    range's result stands; otherwise the earlier one does. (Only the later range's exact
    minimum is read; the earlier range's ``near_min`` is left as it is.)
    """
    for j in range(best_pt.shape[0]):
        b = b_pt[j]
        better = b_conf[j] > best_conf[j] or (b_conf[j] == best_conf[j] and b_d2[j] < best_d2[j])
        if b >= 0 and (best_pt[j] < 0 or better):
            best_pt[j] = b
            best_conf[j] = b_conf[j]
            best_d2[j] = b_d2[j]
    for q in range(near_pt.shape[0]):
        if b_near_min[q] < near_z[q]:
            near_pt[q] = b_near_pt[q]
            near_z[q] = b_near_z[q]


@njit(cache=True, nogil=True)
def cover(geo, best_pt, near_pt, valid_pix, obs, dist_th2, cos_th, h, w, start, stop, covered):
    """The covered flags (see module) of the unmatched valid pixels ``start:stop``, written into
    ``covered`` (matched pixels are left as they are)."""
    for j in range(start, stop):
        if best_pt[j] >= 0:
            continue
        qv = valid_pix[j] // w
        qu = valid_pix[j] - qv * w
        for dv in range(-1, 2):
            vv = qv + dv
            if vv < 0 or vv >= h:
                continue
            for du in range(-1, 2):
                uu = qu + du
                if uu < 0 or uu >= w:
                    continue
                k = near_pt[vv * w + uu]
                if k >= 0 and _match_d2(geo, k, obs, j, dist_th2, cos_th) >= 0.0:
                    covered[j] = True
                    break
            if covered[j]:
                break


@njit(cache=True, nogil=True)
def matches_in_point_order(n, best_pt):
    """``(points, pixels)`` of the matches in point order (each point wins at most one pixel),
    so that merging walks the point arrays forwards instead of jumping around them."""
    num_valid = best_pt.shape[0]
    m = 0
    for j in range(num_valid):
        if best_pt[j] >= 0:
            m += 1
    match = np.full(n, -1, np.int32)
    for j in range(num_valid):
        if best_pt[j] >= 0:
            match[best_pt[j]] = j
    pts = np.empty(m, np.int64)
    pixels = np.empty(m, np.int64)
    i = 0
    for k in range(n):
        if match[k] >= 0:
            pts[i] = k
            pixels[i] = match[k]
            i += 1
    return pts, pixels
