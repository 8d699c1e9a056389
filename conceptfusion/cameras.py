"""Pinhole cameras, frames and depth maps.

One convention holds everywhere in :mod:`conceptfusion`: the **OpenCV camera frame**
(x right, y down, z forward) and poses as 4x4 float64 **camera-to-world** matrices.
Converters from simulator cameras (OpenGL-style poses and depth buffers, MuJoCo, PyBullet)
live at the simulator edge, in :mod:`sim_envs.cameras` and next to each simulator's camera.
"""

from __future__ import annotations

import math

import numpy as np

from conceptfusion._checks import as_array, as_float_array
from conceptfusion.errors import PoseError

__all__ = [
    "intrinsics_from_fovy",
    "check_intrinsics",
    "check_pose",
    "valid_depth_mask",
    "backproject",
    "world_points",
    "normal_map",
    "transform_points",
    "transform_directions",
    "project_points",
    "radial_confidence",
]


def intrinsics_from_fovy(fovy_deg: float, width: int, height: int) -> np.ndarray:
    """Intrinsics of a square-pixel pinhole camera from its vertical field of view.

    ``fy = 0.5 * H / tan(fovy / 2)``, ``fx = fy``, principal point at the image centre
    ``((W - 1) / 2, (H - 1) / 2)`` (pixel centres at integer coordinates).

    Shape:
        returns ``K_33`` float64.
    """
    if not (0.0 < fovy_deg < 180.0):
        raise ValueError(f"fovy_deg: expected a value in (0, 180), got {fovy_deg}")
    if width <= 0 or height <= 0:
        raise ValueError(f"width, height: expected positive sizes, got {width}x{height}")
    f = 0.5 * height / math.tan(math.radians(fovy_deg) / 2.0)
    return np.array([[f, 0.0, (width - 1) / 2.0], [0.0, f, (height - 1) / 2.0], [0.0, 0.0, 1.0]])


def check_intrinsics(K_33) -> np.ndarray:
    """Validate a pinhole intrinsics matrix and return it as float64.

    Expected form ``[[fx, s, cx], [0, fy, cy], [0, 0, 1]]`` with positive, finite focal lengths.
    """
    K = as_array("K_33", K_33, shape=(3, 3)).astype(np.float64)
    if not np.all(np.isfinite(K)):
        raise ValueError("K_33: expected finite values, found NaN or inf")
    if K[0, 0] <= 0 or K[1, 1] <= 0 or not np.allclose(K[2], [0.0, 0.0, 1.0]) or K[1, 0] != 0:
        raise ValueError(
            "K_33: expected [[fx, s, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0, "
            f"got {K.tolist()}"
        )
    return K


def check_pose(T_44, *, atol: float = 1e-4) -> np.ndarray:
    """Validate a rigid camera-to-world transform and return it as float64.

    Raises :class:`PoseError` when the rotation block is not orthonormal with determinant
    +1 (a scaled, sheared or mirrored matrix), the bottom row is not ``[0, 0, 0, 1]`` or
    values are not finite.
    """
    T = as_array("cam_to_world_44", T_44, shape=(4, 4)).astype(np.float64)
    if not np.all(np.isfinite(T)):
        raise PoseError("cam_to_world_44: expected finite values, found NaN or inf")
    if not np.allclose(T[3], [0.0, 0.0, 0.0, 1.0], atol=atol):
        raise PoseError(f"cam_to_world_44: expected bottom row [0, 0, 0, 1], got {T[3].tolist()}")
    R = T[:3, :3]
    err = np.abs(R.T @ R - np.eye(3)).max()
    det = float(np.linalg.det(R))
    if err > atol or abs(det - 1.0) > atol:
        raise PoseError(
            "cam_to_world_44: expected a rigid transform (orthonormal rotation, det +1), "
            f"got |R^T R - I|max = {err:.3g}, det(R) = {det:.4f}"
        )
    return T


def valid_depth_mask(depth_hw: np.ndarray, *, max_depth: float = math.inf) -> np.ndarray:
    """Pixels whose depth is finite, positive and at most ``max_depth`` metres.

    Shape:
        ``depth_hw`` (H, W) float -> (H, W) bool.
    """
    depth = as_float_array("depth_hw", depth_hw, shape=(None, None))
    with np.errstate(invalid="ignore"):
        return np.isfinite(depth) & (depth > 0.0) & (depth <= max_depth)


def backproject(depth_hw: np.ndarray, K_33, *, max_depth: float = math.inf) -> np.ndarray:
    """Vertex map in the camera frame from metric depth along the optical axis.

    Invalid depth (NaN, inf, zero, negative, beyond ``max_depth``) gives NaN vertices.

    Shape:
        ``depth_hw`` (H, W) float -> ``vertex_cam_hw3`` (H, W, 3) float32.
    """
    K = check_intrinsics(K_33)
    valid = valid_depth_mask(depth_hw, max_depth=max_depth)
    h, w = depth_hw.shape
    z = np.where(valid, depth_hw, np.nan).astype(np.float32)
    u = np.arange(w, dtype=np.float32)
    v = np.arange(h, dtype=np.float32)[:, None]
    fx, fy, cx, cy, s = K[0, 0], K[1, 1], K[0, 2], K[1, 2], K[0, 1]
    y = (v - cy) / fy * z
    x = (u - cx - s * (v - cy) / fy) / fx * z
    return np.stack([x, y, z], axis=-1).astype(np.float32, copy=False)


def normal_map(vertex_hw3: np.ndarray) -> np.ndarray:
    """Unit surface normals from a vertex map, by central differences.

    Normals point towards the camera (``n . v < 0`` for a camera-frame vertex map). Border
    pixels and pixels that are invalid or have an invalid neighbour get NaN normals.

    Shape:
        ``vertex_hw3`` (H, W, 3) -> ``normals_hw3`` (H, W, 3) float32.
    """
    v = as_float_array("vertex_hw3", vertex_hw3, shape=(None, None, 3))
    n = np.full(v.shape, np.nan, dtype=np.float32)
    if v.shape[0] < 3 or v.shape[1] < 3:
        return n
    dx = v[1:-1, 2:] - v[1:-1, :-2]
    dy = v[2:, 1:-1] - v[:-2, 1:-1]
    c = np.cross(dx, dy)
    norm = np.linalg.norm(c, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        c = c / norm
        flip = np.sum(c * v[1:-1, 1:-1], axis=-1, keepdims=True) > 0
    c = np.where(flip, -c, c)
    c[~np.isfinite(norm[..., 0]) | (norm[..., 0] == 0) | ~np.isfinite(v[1:-1, 1:-1, 2])] = np.nan
    n[1:-1, 1:-1] = c
    return n


def transform_points(T_44: np.ndarray, points_n3: np.ndarray) -> np.ndarray:
    """Apply a 4x4 rigid transform to points.

    Shape:
        ``T_44`` (4, 4), ``points_n3`` (..., 3) -> (..., 3), dtype of ``points_n3``.
    """
    T = np.asarray(T_44)
    return (points_n3 @ T[:3, :3].T.astype(points_n3.dtype) + T[:3, 3].astype(points_n3.dtype))


def world_points(depth_hw: np.ndarray, K_33, cam_to_world_44, *, max_depth: float = math.inf, stride: int = 1) -> np.ndarray:
    """World points of a posed depth image's valid pixels (every ``stride``-th row and column).

    Invalid depth (see :func:`backproject`) gives no point; the transform is done in float64.

    Shape:
        ``depth_hw`` (H, W), ``K_33`` (3, 3), ``cam_to_world_44`` (4, 4) -> (N, 3) float64,
        N <= ceil(H / stride) * ceil(W / stride).
    """
    K = np.asarray(K_33, np.float64).copy()
    K[:2] /= stride  # sample (r, c) is pixel (stride r, stride c)
    cam = backproject(np.asarray(depth_hw)[::stride, ::stride], K, max_depth=max_depth).reshape(-1, 3)
    cam = cam[np.isfinite(cam).all(axis=1)]
    return transform_points(np.asarray(cam_to_world_44, np.float64), cam.astype(np.float64))


def transform_directions(T_44: np.ndarray, dirs_n3: np.ndarray) -> np.ndarray:
    """Rotate direction vectors (normals) by the rotation block of a 4x4 transform.

    Shape:
        ``T_44`` (4, 4), ``dirs_n3`` (..., 3) -> (..., 3).
    """
    T = np.asarray(T_44)
    return dirs_n3 @ T[:3, :3].T.astype(dirs_n3.dtype)


def project_points(points_cam_n3: np.ndarray, K_33: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pinhole projection of camera-frame points.

    Shape:
        ``points_cam_n3`` (N, 3) -> ``uv_n2`` (N, 2) float pixel coordinates, ``z_n`` (N,) depth.
        Points with ``z <= 0`` get ``uv = nan``.
    """
    z = points_cam_n3[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        zi = np.where(z > 0, 1.0 / z, np.nan)
    x = points_cam_n3[:, 0] * zi
    y = points_cam_n3[:, 1] * zi
    u = K_33[0, 0] * x + K_33[0, 1] * y + K_33[0, 2]
    v = K_33[1, 1] * y + K_33[1, 2]
    return np.stack([u, v], axis=-1), z


def radial_confidence(height: int, width: int, K_33, *, sigma: float = 0.6) -> np.ndarray:
    """Per-pixel fusion confidence ``alpha = exp(-gamma^2 / (2 sigma^2))`` (paper eqs. 1-2).

    ``gamma`` is the pixel's radial distance from the principal point, normalised by the
    image's half-diagonal ``sqrt((W/2)^2 + (H/2)^2)``, so ``gamma`` is about 1 at the corners.

    Shape:
        returns (H, W) float32 in (0, 1].
    """
    K = check_intrinsics(K_33)
    if sigma <= 0:
        raise ValueError(f"sigma: expected a positive value, got {sigma}")
    u = np.arange(width, dtype=np.float64) - K[0, 2]
    v = np.arange(height, dtype=np.float64)[:, None] - K[1, 2]
    gamma2 = (u**2 + v**2) / ((width / 2.0) ** 2 + (height / 2.0) ** 2)
    return np.exp(-gamma2 / (2.0 * sigma**2)).astype(np.float32)
