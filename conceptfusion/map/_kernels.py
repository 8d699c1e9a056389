"""Compiled inner loops of fusion (numba).

Fusion touches every fused pixel (merging) once per frame, and queries every map point; as
fused single passes these run several times faster than the equivalent chains of numpy
temporaries (projective association has its own module, ``_association``). Each kernel has a
plain-numpy specification in its docstring and is tested against the map's behaviour, not
re-implemented elsewhere.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["merge_geometry", "merge_features", "mixture_scores", "mixture_scores_many", "frame_points", "lookup_tables"]


@njit(cache=True, nogil=True, error_model="numpy")
def merge_geometry(geo, pts, pix, obs, alpha):
    """Confidence-weighted running means (eqs. 1-2) of position, normal and colour.

    ``geo[p, 0:9] = (c geo[p, 0:9] + a obs[j]) / (c + a)``, normal re-normalised,
    ``geo[p, 9] = c + a`` for each pair ``(p, j)`` of ``pts``, ``pix``; ``a = alpha[j]``.
    Each row is read once into locals and written once (every value rounded to float32
    where it is stored, as an in-place update of the row would round it).
    """
    for i in range(pts.shape[0]):
        p = pts[i]
        j = pix[i]
        a = alpha[j]
        c = geo[p, 9]
        inv = 1.0 / (c + a)
        x0 = np.float32((c * geo[p, 0] + a * obs[j, 0]) * inv)
        x1 = np.float32((c * geo[p, 1] + a * obs[j, 1]) * inv)
        x2 = np.float32((c * geo[p, 2] + a * obs[j, 2]) * inv)
        x3 = np.float32((c * geo[p, 3] + a * obs[j, 3]) * inv)
        x4 = np.float32((c * geo[p, 4] + a * obs[j, 4]) * inv)
        x5 = np.float32((c * geo[p, 5] + a * obs[j, 5]) * inv)
        x6 = np.float32((c * geo[p, 6] + a * obs[j, 6]) * inv)
        x7 = np.float32((c * geo[p, 7] + a * obs[j, 7]) * inv)
        x8 = np.float32((c * geo[p, 8] + a * obs[j, 8]) * inv)
        nn = np.sqrt(x3**2 + x4**2 + x5**2)
        if nn > 1e-12:
            x3 = np.float32(x3 / nn)
            x4 = np.float32(x4 / nn)
            x5 = np.float32(x5 / nn)
        geo[p, 0] = x0
        geo[p, 1] = x1
        geo[p, 2] = x2
        geo[p, 3] = x3
        geo[p, 4] = x4
        geo[p, 5] = x5
        geo[p, 6] = x6
        geo[p, 7] = x7
        geo[p, 8] = x8
        geo[p, 9] = c + a


@njit(cache=True, nogil=True, inline="always")
def _off(i, j):
    """Index of the pair (i, j), i != j, in the packed strict upper triangle of a Gram matrix."""
    if i > j:
        i, j = j, i
    return j * (j - 1) // 2 + i


@njit(cache=True, nogil=True)
def merge_features(point_ids, point_w, point_gram, point_sq, bank_sq, rows, ids, alpha, lut_atom, lut_new, block):
    """Fuse one feature observation into each point's mixture (see ``FeatureStore``).

    For point ``p = rows[i]`` observing bank entry ``b = ids[i]`` with confidence
    ``a = alpha[i]``, with ``dots[k] = <b_k, b>`` read from ``block`` (rows: the point's
    entries through ``lut_atom``, column through ``lut_new``):

    * ``b`` already held in slot ``j``: credit ``e = b`` to slot ``j``;
    * a free slot ``j``: store ``b`` there, fill the Gram row with ``dots``;
    * no free slot: credit ``e = b_j`` with ``j = argmax dots`` (the most similar entry).

    Then ``|S|^2 += 2 a <S, e> + a^2 |e|^2`` and ``w_j += a``. The Gram matrix's diagonal
    is ``bank_sq`` (squared norms of the bank entries), so ``point_gram`` holds only the
    off-diagonal pairs (see ``_off``).
    """
    k_slots = point_ids.shape[1]
    dots = np.zeros(k_slots, np.float64)
    for i in range(rows.shape[0]):
        p = rows[i]
        b = ids[i]
        a = np.float64(alpha[i])
        c = lut_new[b]
        used = 0
        hit = -1
        for k in range(k_slots):
            idk = point_ids[p, k]
            if idk < 0:
                break
            used += 1
            dots[k] = block[lut_atom[idk], c]
            if idk == b:
                hit = k
        if hit >= 0:
            j = hit
            s_dot_e = 0.0
            for k in range(used):
                s_dot_e += point_w[p, k] * dots[k]
            e_sq = np.float64(bank_sq[b])
        elif used < k_slots:
            j = used
            point_ids[p, j] = b
            s_dot_e = 0.0
            for k in range(used):
                s_dot_e += point_w[p, k] * dots[k]
                point_gram[p, _off(k, j)] = dots[k]
            e_sq = np.float64(bank_sq[b])
        else:
            j = 0
            for k in range(1, k_slots):
                if dots[k] > dots[j]:
                    j = k
            s_dot_e = 0.0
            for k in range(k_slots):
                g = bank_sq[point_ids[p, j]] if k == j else point_gram[p, _off(k, j)]
                s_dot_e += point_w[p, k] * g
            e_sq = np.float64(bank_sq[point_ids[p, j]])
        sq = point_sq[p] + 2.0 * a * s_dot_e + a * a * e_sq
        point_sq[p] = sq if sq > 0.0 else 0.0
        point_w[p, j] += alpha[i]


_SCORE_BLOCK = 2048
"""Points per block in :func:`mixture_scores_many` (their ids, weights and norms: 144 kB)."""


@njit(cache=True, nogil=True)
def mixture_scores(point_ids, point_w, point_sq, bank_scores, start, stop, out):
    """Cosine score of points ``start:stop``: ``sum_k w_k bank_scores[id_k] / sqrt(|S|^2)``.

    The sum runs over a point's slots in order up to its first empty one (id -1), in
    float64. Points without a feature (first id -1, or ``|S|^2 <= 0``) get NaN. Writes
    ``out[start:stop]`` (float32); ``nogil``, so disjoint ranges can run on several threads.
    """
    if point_ids.shape[1] == 8:  # the default: a constant slot count lets the loop unroll
        _mixture_range(point_ids, point_w, point_sq, bank_scores, start, stop, out, 8)
    else:
        _mixture_range(point_ids, point_w, point_sq, bank_scores, start, stop, out, point_ids.shape[1])


@njit(cache=True, nogil=True, inline="always")
def _mixture_range(point_ids, point_w, point_sq, bank_scores, start, stop, out, k_slots):
    for p in range(start, stop):
        if point_ids[p, 0] < 0 or point_sq[p] <= 0.0:
            out[p] = np.nan
            continue
        num = 0.0
        for k in range(k_slots):
            idk = point_ids[p, k]
            if idk < 0:
                break
            num += point_w[p, k] * bank_scores[idk]
        out[p] = num / np.sqrt(point_sq[p])


@njit(cache=True, nogil=True)
def mixture_scores_many(point_ids, point_w, point_sq, bank_scores_qb, start, stop, out_qn):
    """:func:`mixture_scores` for ``Q`` queries over points ``start:stop``: ``out_qn[q]`` is
    exactly what ``mixture_scores`` writes for query ``q``. The points go in blocks small
    enough to stay in cache while every query scores them, so the per-point arrays are read
    from memory once instead of ``Q`` times.

    Shape:
        ``bank_scores_qb`` (Q, B) float32, ``out_qn`` (Q, N) float32.
    """
    k_slots = point_ids.shape[1]
    for block in range(start, stop, _SCORE_BLOCK):
        end = min(block + _SCORE_BLOCK, stop)
        for q in range(bank_scores_qb.shape[0]):
            if k_slots == 8:
                _mixture_range(point_ids, point_w, point_sq, bank_scores_qb[q], block, end, out_qn[q], 8)
            else:
                _mixture_range(point_ids, point_w, point_sq, bank_scores_qb[q], block, end, out_qn[q], k_slots)


@njit(cache=True, nogil=True)
def frame_points(depth, rgb, K, cam_to_world, max_depth, conf_hw):
    """Valid pixels of a frame as world points, in one pass.

    Same results as :func:`conceptfusion.cameras.backproject` +
    :func:`~conceptfusion.cameras.normal_map` (central differences, normals facing the
    camera, border and invalid-neighbour pixels dropped) followed by the rigid transform.

    Returns ``(pix, obs, alpha)``: flat pixel indices (V,) int64, observations (V, 9)
    float32 = world position, world normal, colour, and confidences (V,) float32.
    """
    h, w = depth.shape
    fx, s, cx, fy, cy = K[0, 0], K[0, 1], K[0, 2], K[1, 1], K[1, 2]
    ok = np.zeros((h, w), np.bool_)
    vx = np.empty((h, w), np.float32)
    vy = np.empty((h, w), np.float32)
    for r in range(h):
        for c in range(w):
            z = depth[r, c]
            if np.isfinite(z) and z > 0.0 and z <= max_depth:
                ok[r, c] = True
                yy = (r - cy) / fy
                vy[r, c] = yy * z
                vx[r, c] = (c - cx - s * yy) / fx * z
    count = 0
    for r in range(1, h - 1):
        for c in range(1, w - 1):
            if ok[r, c] and ok[r, c - 1] and ok[r, c + 1] and ok[r - 1, c] and ok[r + 1, c]:
                count += 1
    pix = np.empty(count, np.int64)
    obs = np.empty((count, 9), np.float32)
    alpha = np.empty(count, np.float32)
    R = cam_to_world[:3, :3]
    t = cam_to_world[:3, 3]
    i = 0
    for r in range(1, h - 1):
        for c in range(1, w - 1):
            if not (ok[r, c] and ok[r, c - 1] and ok[r, c + 1] and ok[r - 1, c] and ok[r + 1, c]):
                continue
            ax = vx[r, c + 1] - vx[r, c - 1]
            ay = vy[r, c + 1] - vy[r, c - 1]
            az = depth[r, c + 1] - depth[r, c - 1]
            bx = vx[r + 1, c] - vx[r - 1, c]
            by = vy[r + 1, c] - vy[r - 1, c]
            bz = depth[r + 1, c] - depth[r - 1, c]
            nx = ay * bz - az * by
            ny = az * bx - ax * bz
            nz = ax * by - ay * bx
            nn = np.sqrt(nx * nx + ny * ny + nz * nz)
            if not nn > 0.0:
                count -= 1
                continue
            px, py, pz = vx[r, c], vy[r, c], depth[r, c]
            if nx * px + ny * py + nz * pz > 0.0:
                nn = -nn
            nx /= nn
            ny /= nn
            nz /= nn
            for a in range(3):
                obs[i, a] = R[a, 0] * px + R[a, 1] * py + R[a, 2] * pz + t[a]
                obs[i, 3 + a] = R[a, 0] * nx + R[a, 1] * ny + R[a, 2] * nz
                obs[i, 6 + a] = rgb[r, c, a]
            pix[i] = r * w + c
            alpha[i] = conf_hw[r, c]
            i += 1
    return pix[:i], obs[:i], alpha[:i]


@njit(cache=True, nogil=True)
def lookup_tables(point_ids, rows, new_ids, num_bank):
    """Row and column numbering of the bank entries one fusion step compares.

    Returns ``(atoms, lut_atom, cols, lut_new)``: the sorted bank ids held by the points
    ``rows`` and the map from bank id to their position (-1 elsewhere); the same for the
    frame's ids ``new_ids``.
    """
    lut_atom = np.full(num_bank, -1, np.int32)
    lut_new = np.full(num_bank, -1, np.int32)
    for i in range(rows.shape[0]):
        p = rows[i]
        for k in range(point_ids.shape[1]):
            idk = point_ids[p, k]
            if idk < 0:
                break
            lut_atom[idk] = 0
        lut_new[new_ids[i]] = 0
    na = 0
    nc = 0
    for b in range(num_bank):
        if lut_atom[b] == 0:
            lut_atom[b] = na
            na += 1
        if lut_new[b] == 0:
            lut_new[b] = nc
            nc += 1
    atoms = np.empty(na, np.int64)
    cols = np.empty(nc, np.int64)
    for b in range(num_bank):
        if lut_atom[b] >= 0:
            atoms[lut_atom[b]] = b
        if lut_new[b] >= 0:
            cols[lut_new[b]] = b
    return atoms, lut_atom, cols, lut_new
