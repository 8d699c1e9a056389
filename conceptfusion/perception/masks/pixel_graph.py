"""The pixel graph of :mod:`conceptfusion.perception.masks.rgbd`: normals, edge weights and their order.

Compiled loops (numba) that compute, value for value, what the array formulation in the
proposer's docstring describes: every operation is done in the same precision and the same
order (float32 throughout, three-term sums left to right, float64 only for the final sum of
the colour and geometric costs), so the masks do not depend on which formulation runs. The
tests hold these kernels to the array formulation bit for bit.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from conceptfusion.perception.masks.rgbd_config import RGBDProposerConfig

__all__ = ["edge_aware_normals", "edge_weights", "stable_order"]

_F32_MAX = float(np.finfo(np.float32).max)


def edge_aware_normals(vertex_hw3: np.ndarray) -> np.ndarray:
    """Unit normals from one-sided differences, each axis taking the side with the smaller
    depth change, so pixels next to an occluding edge keep their own surface's normal.

    Orientation is irrelevant to the proposer (only ``n_p . n_q`` and convexity use them,
    both invariant to flipping both normals; a consistent sign is kept by facing the camera).
    NaN where no valid neighbour exists on either side along an axis.

    Shape:
        (H, W, 3) -> (H, W, 3) float32.
    """
    return _normals(np.ascontiguousarray(vertex_hw3, np.float32))


@njit(cache=True, nogil=True, error_model="numpy")
def _tangent(v, i, j, di, dj, out):
    """One-sided difference at (i, j) along (di, dj): backward when the forward one is missing
    or has the larger depth change."""
    h, w = v.shape[0], v.shape[1]
    nan = np.float32(np.nan)
    has_f = i + di < h and j + dj < w
    has_b = i - di >= 0 and j - dj >= 0
    fz = v[i + di, j + dj, 2] - v[i, j, 2] if has_f else nan
    bz = v[i, j, 2] - v[i - di, j - dj, 2] if has_b else nan
    if math.isnan(fz) or abs(bz) < abs(fz):
        for c in range(3):
            out[c] = v[i, j, c] - v[i - di, j - dj, c] if has_b else nan
    else:
        for c in range(3):
            out[c] = v[i + di, j + dj, c] - v[i, j, c]


@njit(cache=True, nogil=True, error_model="numpy")
def _normals(v):
    h, w = v.shape[0], v.shape[1]
    out = np.empty((h, w, 3), np.float32)
    a = np.empty(3, np.float32)
    b = np.empty(3, np.float32)
    for i in range(h):
        for j in range(w):
            _tangent(v, i, j, 0, 1, a)
            _tangent(v, i, j, 1, 0, b)
            n0 = a[1] * b[2] - a[2] * b[1]
            n1 = a[2] * b[0] - a[0] * b[2]
            n2 = a[0] * b[1] - a[1] * b[0]
            norm = np.float32(math.sqrt((n0 * n0 + n1 * n1) + n2 * n2))
            n0, n1, n2 = n0 / norm, n1 / norm, n2 / norm
            if (n0 * v[i, j, 0] + n1 * v[i, j, 1]) + n2 * v[i, j, 2] > 0:
                n0, n1, n2 = -n0, -n1, -n2
            out[i, j, 0], out[i, j, 1], out[i, j, 2] = n0, n1, n2
    return out


def edge_weights(lab_hw3: np.ndarray, inv_hw: np.ndarray, vertex_hw3: np.ndarray, normals_hw3: np.ndarray,
                 valid_hw: np.ndarray, cfg: RGBDProposerConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Right and down 4-neighbour edges with their combined weights (see the cues of
    :mod:`conceptfusion.perception.masks.rgbd`): right edges in raster order, then down edges.

    Shape:
        ``lab_hw3`` (H, W, 3) float32 CIELAB, ``inv_hw`` (H, W) float32 inverse depth (NaN where
        invalid), vertex and normals (H, W, 3) float32, ``valid_hw`` (H, W) bool -> src (E,),
        dst (E,) int64, weight (E,) float32 with E = H (W - 1) + (H - 1) W.
    """
    f32 = np.float32
    consts = np.array([cfg.lightness_weight, 1.0, 1.0, cfg.color_scale, cfg.depth_tol,
                       1.0 - math.cos(math.radians(cfg.normal_tol_deg)), cfg.convex_weight, cfg.max_term], np.float32)
    return _edge_weights(np.ascontiguousarray(lab_hw3, f32), np.ascontiguousarray(inv_hw, f32),
                         np.ascontiguousarray(vertex_hw3, f32), np.ascontiguousarray(normals_hw3, f32),
                         np.ascontiguousarray(valid_hw, np.bool_), consts, float(2.0 * cfg.max_term))


@njit(cache=True, nogil=True, error_model="numpy")
def _fmin(a, b):
    if math.isnan(a):
        return b
    if math.isnan(b):
        return a
    return min(a, b)


@njit(cache=True, nogil=True, error_model="numpy")
def _nan_to_num(x):
    if math.isnan(x):
        return np.float32(0.0)
    if math.isinf(x):
        return np.float32(_F32_MAX) if x > 0 else np.float32(-_F32_MAX)
    return x


@njit(cache=True, nogil=True, error_model="numpy")
def _depth_jump(inv, i, j, di, dj):
    """Relative departure of the inverse-depth step from (i, j) to its neighbour along
    (di, dj) from the adjacent steps; NaN where either pixel is invalid."""
    h, w = inv.shape
    nan = np.float32(np.nan)
    p, q = inv[i, j], inv[i + di, j + dj]
    s = q - p
    prev = p - inv[i - di, j - dj] if (i - di >= 0 and j - dj >= 0) else nan
    nxt = inv[i + 2 * di, j + 2 * dj] - q if (i + 2 * di < h and j + 2 * dj < w) else nan
    if math.isnan(prev) and math.isnan(nxt):
        dev = abs(s)
    else:
        dev = _fmin(abs(s - prev), abs(s - nxt))
    return dev / (np.float32(0.5) * (p + q))


@njit(cache=True, nogil=True, error_model="numpy")
def _edge_weights(lab, inv, vert, nrm, valid, consts, both_invalid_cost):
    h, w = inv.shape
    lw0, lw1, lw2, color_scale, depth_tol, normal_den, convex_weight, max_term = (
        consts[0], consts[1], consts[2], consts[3], consts[4], consts[5], consts[6], consts[7])
    e = h * (w - 1) + (h - 1) * w
    src = np.empty(e, np.int64)
    dst = np.empty(e, np.int64)
    weight = np.empty(e, np.float32)
    k = 0
    for axis in range(2):  # right neighbours, then down neighbours
        di, dj = (0, 1) if axis == 0 else (1, 0)
        for i in range(h - di):
            for j in range(w - dj):
                i2, j2 = i + di, j + dj
                c0 = (lab[i, j, 0] - lab[i2, j2, 0]) * lw0
                c1 = (lab[i, j, 1] - lab[i2, j2, 1]) * lw1
                c2 = (lab[i, j, 2] - lab[i2, j2, 2]) * lw2
                color = np.float32(math.sqrt((c0 * c0 + c1 * c1) + c2 * c2)) / color_scale
                depth_cost = _depth_jump(inv, i, j, di, dj) / depth_tol
                dot = (nrm[i, j, 0] * nrm[i2, j2, 0] + nrm[i, j, 1] * nrm[i2, j2, 1]) + nrm[i, j, 2] * nrm[i2, j2, 2]
                cv = ((nrm[i, j, 0] - nrm[i2, j2, 0]) * (vert[i, j, 0] - vert[i2, j2, 0])
                      + (nrm[i, j, 1] - nrm[i2, j2, 1]) * (vert[i, j, 1] - vert[i2, j2, 1])) \
                    + (nrm[i, j, 2] - nrm[i2, j2, 2]) * (vert[i, j, 2] - vert[i2, j2, 2])
                normal_cost = _nan_to_num((np.float32(1.0) - dot) / normal_den)
                if cv > 0:
                    normal_cost = convex_weight * normal_cost
                va, vb = valid[i, j], valid[i2, j2]
                if va and vb:
                    geo = float(min(_nan_to_num(depth_cost), max_term) + min(normal_cost, max_term))
                elif va != vb:
                    geo = both_invalid_cost
                else:
                    geo = 0.0
                weight[k] = np.float32(float(min(color, max_term)) + geo)
                src[k] = i * w + j
                dst[k] = i2 * w + j2
                k += 1
    return src, dst, weight


def stable_order(weight_e: np.ndarray) -> np.ndarray:
    """``np.argsort(weight_e, kind="stable")``, faster: float32 bits mapped to unsigned keys
    that order as the floats do (negative: all bits flipped; otherwise the sign bit set;
    -0.0 as 0.0) and sorted by a stable radix sort give the same permutation. NaN weights
    fall back to the stable argsort.

    Shape:
        (E,) float32 -> (E,) int64.
    """
    w = np.ascontiguousarray(weight_e, np.float32)
    if np.isnan(w).any():
        return np.argsort(w, kind="stable")
    bits = np.where(w == 0, np.float32(0.0), w).view(np.uint32)
    keys = np.where(bits >> np.uint32(31), ~bits, bits | np.uint32(0x80000000))
    return _radix_argsort_u32(keys)


@njit(cache=True, nogil=True, error_model="numpy")
def _radix_argsort_u32(keys):
    """Stable argsort of unsigned 32-bit keys: LSD radix sort, four 8-bit passes (a pass whose
    byte is the same for every key is skipped). Shape: (E,) uint32 -> (E,) int64."""
    n = keys.shape[0]
    order = np.empty(n, np.int64)
    for i in range(n):
        order[i] = i
    tmp = np.empty(n, np.int64)
    counts = np.zeros(256, np.int64)
    for byte in range(4):
        shift = 8 * byte
        for b in range(256):
            counts[b] = 0
        for i in range(n):
            counts[(np.int64(keys[i]) >> shift) & 255] += 1
        constant = False
        for b in range(256):
            constant |= counts[b] == n
        if constant:
            continue
        total = 0
        for b in range(256):
            c = counts[b]
            counts[b] = total
            total += c
        for i in range(n):
            j = order[i]
            b = (np.int64(keys[j]) >> shift) & 255
            tmp[counts[b]] = j
            counts[b] += 1
        for i in range(n):
            order[i] = tmp[i]
    return order
