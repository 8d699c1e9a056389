"""Exact synthetic RGB-D of box scenes, for tests, benchmarks and the simulator-free demo.

Axis-aligned boxes are ray-cast analytically from a pinhole camera, so depth, instance ids
and surfaces are known exactly: a fused map can be checked against them to the millimetre.
World frame: z up, metres. Cameras follow the package convention (OpenCV, camera-to-world).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from conceptfusion.cameras import check_intrinsics, check_pose
from conceptfusion.frames import RGBDFrame

__all__ = ["Box", "look_at", "orbit_poses", "render_boxes", "tabletop_boxes"]


@dataclass(frozen=True)
class Box:
    """An axis-aligned box with a name and a colour."""

    name: str
    center: tuple[float, float, float]
    """Centre in world metres."""
    size: tuple[float, float, float]
    """Full extent along x, y, z in metres."""
    color: tuple[int, int, int]
    """Base RGB colour."""

    @property
    def lo(self) -> np.ndarray:
        return np.asarray(self.center, float) - np.asarray(self.size, float) / 2

    @property
    def hi(self) -> np.ndarray:
        return np.asarray(self.center, float) + np.asarray(self.size, float) / 2


def look_at(eye, target, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """OpenCV camera-to-world pose of a camera at ``eye`` looking at ``target``.

    Shape:
        (3,), (3,), (3,) -> (4, 4) float64.
    """
    eye = np.asarray(eye, float)
    fwd = np.asarray(target, float) - eye
    norm = np.linalg.norm(fwd)
    if norm < 1e-9:
        raise ValueError("look_at: eye and target coincide")
    fwd /= norm
    right = np.cross(fwd, np.asarray(up, float))
    if np.linalg.norm(right) < 1e-9:
        raise ValueError("look_at: viewing direction is parallel to 'up'")
    right /= np.linalg.norm(right)
    down = np.cross(fwd, right)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = right, down, fwd, eye
    return T


def orbit_poses(center, radius: float, height: float, num: int, *, start_deg: float = 0.0, sweep_deg: float = 360.0):
    """``num`` look-at poses on a horizontal circle around ``center``, ``height`` above it."""
    c = np.asarray(center, float)
    out = []
    for a in np.radians(start_deg + sweep_deg * np.arange(num) / max(num, 1)):
        eye = c + np.array([radius * np.cos(a), radius * np.sin(a), height])
        out.append(look_at(eye, c))
    return out


def tabletop_boxes() -> list[Box]:
    """A floor, a table and six coloured objects on it (index = instance id)."""
    return [
        Box("floor", (0.0, 0.0, -0.05), (6.0, 6.0, 0.1), (150, 150, 150)),
        Box("table", (0.0, 0.0, 0.375), (1.2, 0.8, 0.05), (120, 75, 40)),
        Box("red box", (-0.35, -0.2, 0.46), (0.12, 0.12, 0.12), (200, 30, 30)),
        Box("green box", (0.3, 0.15, 0.45), (0.15, 0.1, 0.1), (40, 160, 60)),
        Box("blue box", (0.0, 0.25, 0.48), (0.1, 0.1, 0.16), (30, 60, 200)),
        Box("yellow box", (0.35, -0.22, 0.44), (0.14, 0.14, 0.08), (230, 210, 40)),
        Box("purple box", (-0.3, 0.22, 0.45), (0.1, 0.16, 0.1), (130, 50, 160)),
        Box("orange box", (0.0, -0.2, 0.45), (0.09, 0.09, 0.1), (240, 130, 30)),
    ]


def render_boxes(boxes: list[Box], K_33, cam_to_world_44, height: int, width: int) -> RGBDFrame:
    """Ray-cast axis-aligned boxes (see the module docstring).

    Shading: base colour times a Lambertian term of a fixed light, with a faint checker
    texture so surfaces are not flat colours.

    Shape:
        returns a frame with ``rgb`` (H, W, 3) uint8; ``depth`` (H, W) float32 metres along
        the optical axis, ``inf`` where nothing is hit; ``segmentation`` (H, W) int32 box index,
        -1 for none; ``K`` (3, 3) and ``cam_to_world`` (4, 4) float64 (OpenCV pose).
    """
    K = check_intrinsics(K_33)
    T = check_pose(cam_to_world_44)
    u, v = np.meshgrid(np.arange(width, dtype=np.float64), np.arange(height, dtype=np.float64))
    y = (v - K[1, 2]) / K[1, 1]
    x = (u - K[0, 2] - K[0, 1] * y) / K[0, 0]
    rays_cam = np.stack([x, y, np.ones_like(x)], axis=-1).reshape(-1, 3)  # z = 1: t is depth
    d = rays_cam @ T[:3, :3].T
    o = T[:3, 3]
    best_t = np.full(len(d), np.inf)
    best_id = np.full(len(d), -1, np.int32)
    best_axis = np.zeros(len(d), np.int64)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / d
        for i, b in enumerate(boxes):
            t1 = (b.lo - o) * inv
            t2 = (b.hi - o) * inv
            tmin = np.minimum(t1, t2)
            tmax = np.maximum(t1, t2)
            tmin = np.where(np.isnan(tmin), -np.inf, tmin)
            tmax = np.where(np.isnan(tmax), np.inf, tmax)
            t_near = tmin.max(axis=1)
            t_far = tmax.min(axis=1)
            hit = (t_near <= t_far) & (t_near > 1e-6) & (t_near < best_t)
            best_t[hit] = t_near[hit]
            best_id[hit] = i
            best_axis[hit] = tmin[hit].argmax(axis=1)
    hit = best_id >= 0
    normal = np.zeros_like(d)
    normal[np.arange(len(d)), best_axis] = -np.sign(d[np.arange(len(d)), best_axis])
    light = np.array([0.4, 0.3, 0.86])
    shade = 0.55 + 0.45 * np.clip(normal @ light, 0.0, 1.0)
    pts = o + best_t[:, None] * d
    checker = ((np.floor(np.where(hit[:, None], pts, 0.0) / 0.05).sum(axis=1)) % 2) * 0.08 + 0.92
    colors = np.array([b.color for b in boxes] + [(0, 0, 0)], np.float64)
    rgb = colors[best_id] * (shade * checker)[:, None]
    rgb[~hit] = (30, 30, 40)
    depth = np.where(hit, best_t, np.inf).astype(np.float32)
    return RGBDFrame(
        rgb=np.clip(rgb, 0, 255).astype(np.uint8).reshape(height, width, 3),
        depth=depth.reshape(height, width),
        K=K,
        cam_to_world=T,
        segmentation=best_id.reshape(height, width),
    )
