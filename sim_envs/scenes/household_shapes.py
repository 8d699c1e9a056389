"""Simulator-neutral shapes of a household: the solid boxes of its walls, the extent of the ground
around the rooms, and the test that no furniture stands in a wall.

Both simulators build walls from :func:`wall_boxes`, so an apartment has the same walls in MuJoCo
and PyBullet: each wall is cut into solid spans between its doors, plus a lintel above every door
(the wall above :data:`LINTEL_HEIGHT` is solid), and every piece is two half-thickness slabs, one
per face, so each face can carry its own material.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["LINTEL_HEIGHT", "WallBox", "wall_boxes", "ground_half", "furniture_in_walls", "WALL_OVERLAP_TOL"]

LINTEL_HEIGHT = 2.1
"""Height of the top of a door opening (metres); the wall above it is solid."""

WALL_OVERLAP_TOL = 0.01
"""How deep (metres) a piece of furniture's footprint may reach into a wall before the scene is
refused: furniture stands with its back against a wall (measured: no piece of the shipped v1 and
v2 apartments, calibration, gate and sealed sets included, touches a wall at all)."""


@dataclass(frozen=True)
class WallBox:
    """One solid box of a wall, in world coordinates.

    ``centre`` (3,) metres; ``yaw`` of the wall's direction (radians); ``half`` (3,) half sizes
    along the wall, across it and up; ``material`` of the face it carries; ``name`` unique in the
    scene (``<wall id>_<piece><l|r>``).
    """

    name: str
    centre: tuple[float, float, float]
    yaw: float
    half: tuple[float, float, float]
    material: str


def _solid_pieces(wall) -> list[tuple[float, float, float, float]]:
    """(from, to, z0, z1) of the solid spans between doors and of the lintels above doors."""
    pieces = [(a, b, 0.0, wall.height) for a, b in wall.solid_spans()]
    pieces += [(off, off + width, LINTEL_HEIGHT, wall.height) for off, width in wall.doors if wall.height > LINTEL_HEIGHT]
    return pieces


def wall_boxes(wall) -> list[WallBox]:
    """The boxes of a :class:`~sim_envs.scenes.household_format.Wall`: per solid piece, a
    left-face slab and a right-face slab (materials ``wall.materials[0]`` and ``[1]``)."""
    (sx, sy), (ex, ey) = wall.start, wall.end
    ux, uy = (ex - sx) / wall.length, (ey - sy) / wall.length
    nx, ny = -uy, ux  # left normal
    yaw = math.atan2(uy, ux)
    q = wall.thickness / 4
    out = []
    for k, (a, b, z0, z1) in enumerate(_solid_pieces(wall)):
        m = (a + b) / 2
        cx, cy = sx + ux * m, sy + uy * m
        for side, sign, mat in (("l", 1, wall.materials[0]), ("r", -1, wall.materials[1])):
            out.append(WallBox(f"{wall.id}_{k}{side}", (cx + sign * nx * q, cy + sign * ny * q, (z0 + z1) / 2), yaw,
                               ((b - a) / 2, q, (z1 - z0) / 2), mat))
    return out


def ground_half(scene) -> float:
    """Half size (m) of the square ground centred on the origin: 5 m past the farthest room corner
    (at least 10 m)."""
    ext = max(max(abs(v) for r in scene.rooms for corner in r.floor for v in corner), 5.0)
    return ext + 5.0


def _penetration(c1, yaw1, half1, c2, yaw2, half2) -> float:
    """How deep two rotated rectangles overlap (separating-axis test): the smallest overlap along
    the four edge normals; <= 0 when they are apart."""
    axes = [(math.cos(t), math.sin(t)) for t in (yaw1, yaw1 + math.pi / 2, yaw2, yaw2 + math.pi / 2)]
    d = np.subtract(c2, c1)
    depth = math.inf
    for ax in axes:
        r1 = sum(abs(h * (math.cos(yaw1 + j * math.pi / 2) * ax[0] + math.sin(yaw1 + j * math.pi / 2) * ax[1])) for j, h in enumerate(half1))
        r2 = sum(abs(h * (math.cos(yaw2 + j * math.pi / 2) * ax[0] + math.sin(yaw2 + j * math.pi / 2) * ax[1])) for j, h in enumerate(half2))
        depth = min(depth, r1 + r2 - abs(d[0] * ax[0] + d[1] * ax[1]))
    return depth


def furniture_in_walls(walls, furniture, tol: float = WALL_OVERLAP_TOL) -> list[tuple[int, str, float]]:
    """``(furniture index, wall id, depth)`` for every piece whose footprint reaches more than
    ``tol`` metres into a solid span of a wall (doors are gaps; lintels are above any furniture
    a scene may hold, so only the floor-to-ceiling spans count)."""
    found = []
    for j, f in enumerate(furniture):
        half_f = (f.size[0] / 2, f.size[1] / 2)
        for w in walls:
            (sx, sy), (ex, ey) = w.start, w.end
            ux, uy = (ex - sx) / w.length, (ey - sy) / w.length
            yaw = math.atan2(uy, ux)
            for a, b in w.solid_spans():
                m = (a + b) / 2
                depth = _penetration(f.position[:2], f.yaw, half_f, (sx + ux * m, sy + uy * m), yaw, ((b - a) / 2, w.thickness / 2))
                if depth > tol:
                    found.append((j, w.id, depth))
                    break
    return found
