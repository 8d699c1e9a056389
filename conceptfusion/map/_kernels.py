"""Compiled inner loops of fusion (numba).

Fusion touches every map point (projection) and every fused pixel (merging) once per
frame; as fused single passes these run several times faster than the equivalent chains
of numpy temporaries. Each kernel has a plain-numpy specification in its docstring and is
tested against the map's behaviour, not re-implemented elsewhere.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["associate", "merge_geometry", "merge_features", "mixture_scores"]


@njit(cache=True, nogil=True)
def associate(geo, n, world_to_cam, K, pixel_to_valid, verts, nrms, dist_th2, cos_th, h, w):
    """Projective data association.

    For each of the first ``n`` map points (rows of ``geo``: position 0:3, normal 3:6,
    confidence 9), project into the frame; if it lands on a valid pixel ``j`` within
    ``sqrt(dist_th2)`` of that pixel's vertex ``verts[j]`` with normals agreeing
    (``dot >= cos_th``), it is a candidate for ``j``. Per pixel the candidate with the
    highest confidence wins, ties to the nearest, then to the lowest point index.

    A valid pixel with no candidate is *covered* when the nearest point projecting onto one
    of its 8 neighbours passes the same distance and normal tests: the surface there is
    already in the map at the map's density, so the pixel adds no new point.

    Returns ``(points, pixels, covered)``: matched map point indices and valid-pixel
    indices, (M,) int64 ordered by pixel, and (V,) bool over the valid pixels.
    """
    num_valid = verts.shape[0]
    best_pt = np.full(num_valid, -1, np.int64)
    best_conf = np.zeros(num_valid, np.float32)
    best_d2 = np.zeros(num_valid, np.float32)
    near_pt = np.full(h * w, -1, np.int64)  # nearest point projecting onto each pixel
    near_z = np.full(h * w, np.inf, np.float32)
    r00, r01, r02, t0 = world_to_cam[0, 0], world_to_cam[0, 1], world_to_cam[0, 2], world_to_cam[0, 3]
    r10, r11, r12, t1 = world_to_cam[1, 0], world_to_cam[1, 1], world_to_cam[1, 2], world_to_cam[1, 3]
    r20, r21, r22, t2 = world_to_cam[2, 0], world_to_cam[2, 1], world_to_cam[2, 2], world_to_cam[2, 3]
    fx, s, cx, fy, cy = K[0, 0], K[0, 1], K[0, 2], K[1, 1], K[1, 2]
    for k in range(n):
        x, y, z = geo[k, 0], geo[k, 1], geo[k, 2]
        zc = r20 * x + r21 * y + r22 * z + t2
        if zc <= 0.0:
            continue
        xc = (r00 * x + r01 * y + r02 * z + t0) / zc
        yc = (r10 * x + r11 * y + r12 * z + t1) / zc
        u = np.rint(fx * xc + s * yc + cx)
        v = np.rint(fy * yc + cy)
        if u < 0 or u >= w or v < 0 or v >= h:
            continue
        q = int(v) * w + int(u)
        if zc < near_z[q]:
            near_z[q] = zc
            near_pt[q] = k
        j = pixel_to_valid[q]
        if j < 0:
            continue
        if not _compatible(geo, k, verts, nrms, j, dist_th2, cos_th):
            continue
        dx = x - verts[j, 0]
        dy = y - verts[j, 1]
        dz = z - verts[j, 2]
        d2 = dx * dx + dy * dy + dz * dz
        c = geo[k, 9]
        b = best_pt[j]
        if b < 0 or c > best_conf[j] or (c == best_conf[j] and d2 < best_d2[j]):
            best_pt[j] = k
            best_conf[j] = c
            best_d2[j] = d2
    covered = np.zeros(num_valid, np.bool_)
    m = 0
    for q in range(h * w):
        j = pixel_to_valid[q]
        if j < 0:
            continue
        if best_pt[j] >= 0:
            m += 1
            continue
        qv = q // w
        qu = q - qv * w
        for dv in range(-1, 2):
            for du in range(-1, 2):
                vv = qv + dv
                uu = qu + du
                if vv < 0 or vv >= h or uu < 0 or uu >= w:
                    continue
                k = near_pt[vv * w + uu]
                if k >= 0 and _compatible(geo, k, verts, nrms, j, dist_th2, cos_th):
                    covered[j] = True
    pts = np.empty(m, np.int64)
    pix = np.empty(m, np.int64)
    i = 0
    for j in range(num_valid):
        if best_pt[j] >= 0:
            pts[i] = best_pt[j]
            pix[i] = j
            i += 1
    return pts, pix, covered


@njit(cache=True, nogil=True, inline="always")
def _compatible(geo, k, verts, nrms, j, dist_th2, cos_th):
    """Map point ``k`` and frame vertex ``j`` are within the distance and angle thresholds."""
    dx = geo[k, 0] - verts[j, 0]
    dy = geo[k, 1] - verts[j, 1]
    dz = geo[k, 2] - verts[j, 2]
    if dx * dx + dy * dy + dz * dz >= dist_th2:
        return False
    return geo[k, 3] * nrms[j, 0] + geo[k, 4] * nrms[j, 1] + geo[k, 5] * nrms[j, 2] >= cos_th


@njit(cache=True, nogil=True)
def merge_geometry(geo, pts, pix, obs, alpha):
    """Confidence-weighted running means (eqs. 1-2) of position, normal and colour.

    ``geo[p, 0:9] = (c geo[p, 0:9] + a obs[j]) / (c + a)``, normal re-normalised,
    ``geo[p, 9] = c + a`` for each pair ``(p, j)`` of ``pts``, ``pix``; ``a = alpha[j]``.
    """
    for i in range(pts.shape[0]):
        p = pts[i]
        j = pix[i]
        a = alpha[j]
        c = geo[p, 9]
        inv = 1.0 / (c + a)
        for col in range(9):
            geo[p, col] = (c * geo[p, col] + a * obs[j, col]) * inv
        nn = np.sqrt(geo[p, 3] ** 2 + geo[p, 4] ** 2 + geo[p, 5] ** 2)
        if nn > 1e-12:
            geo[p, 3] /= nn
            geo[p, 4] /= nn
            geo[p, 5] /= nn
        geo[p, 9] = c + a


@njit(cache=True, nogil=True, inline="always")
def _tri(i, j, k):
    """Index of (i, j) in the row-major upper triangle of a k x k matrix."""
    if i > j:
        i, j = j, i
    return i * (2 * k - i + 1) // 2 + (j - i)


@njit(cache=True, nogil=True)
def merge_features(point_ids, point_w, point_gram, point_sq, rows, ids, alpha, lut_atom, lut_new, block, new_sq):
    """Fuse one feature observation into each point's mixture (see ``FeatureStore``).

    For point ``p = rows[i]`` observing bank entry ``b = ids[i]`` with confidence
    ``a = alpha[i]``, with ``dots[k] = <b_k, b>`` read from ``block`` (rows: the point's
    entries through ``lut_atom``, column through ``lut_new``):

    * ``b`` already held in slot ``j``: credit ``e = b`` to slot ``j``;
    * a free slot ``j``: store ``b`` there, fill the Gram row with ``dots``;
    * no free slot: credit ``e = b_j`` with ``j = argmax dots`` (the most similar entry).

    Then ``|S|^2 += 2 a <S, e> + a^2 |e|^2`` and ``w_j += a``.
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
            e_sq = np.float64(new_sq[c])
        elif used < k_slots:
            j = used
            point_ids[p, j] = b
            s_dot_e = 0.0
            for k in range(used):
                s_dot_e += point_w[p, k] * dots[k]
                point_gram[p, _tri(k, j, k_slots)] = dots[k]
            point_gram[p, _tri(j, j, k_slots)] = new_sq[c]
            e_sq = np.float64(new_sq[c])
        else:
            j = 0
            for k in range(1, k_slots):
                if dots[k] > dots[j]:
                    j = k
            s_dot_e = 0.0
            for k in range(k_slots):
                s_dot_e += point_w[p, k] * point_gram[p, _tri(k, j, k_slots)]
            e_sq = np.float64(point_gram[p, _tri(j, j, k_slots)])
        sq = point_sq[p] + 2.0 * a * s_dot_e + a * a * e_sq
        point_sq[p] = sq if sq > 0.0 else 0.0
        point_w[p, j] += alpha[i]


@njit(cache=True, nogil=True)
def mixture_scores(point_ids, point_w, point_sq, bank_scores, n):
    """Cosine score of each point's mixture: ``sum_k w_k bank_scores[id_k] / sqrt(|S|^2)``.

    Points without a feature (first id -1) get NaN. Returns (n,) float32.
    """
    out = np.empty(n, np.float32)
    k_slots = point_ids.shape[1]
    for p in range(n):
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
    return out


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
