"""Small triangle meshes with texture coordinates, and the primitives shapes are built from.

A :class:`MeshData` holds vertices, triangles and one texture coordinate per vertex (seams are
split vertices), so it writes straight to an OBJ that MuJoCo and PyBullet both read with its
texture. A :class:`Part` is a piece of a shape together with how it collides: its convex hull
(``"hull"``), a thin-walled open vessel cut into hulls of wall sectors plus its floor
(``"hollow"``), or not at all (``"none"``, decoration).

Frames: z up, metres; a profile is ``(r, z)`` pairs revolved about the z axis.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = [
    "MeshData", "Part", "merge", "revolve", "box", "cylinder", "ellipsoid", "tube_arc", "slab",
    "transform", "rotation", "box_uv",
]


@dataclass(frozen=True)
class MeshData:
    """A triangle mesh with a texture coordinate per vertex.

    Shape:
        ``vertices`` (V, 3) float64 metres; ``faces`` (F, 3) int64 counter-clockwise seen from
        outside; ``uv`` (V, 2) float64 in [0, 1].
    """

    vertices: np.ndarray
    faces: np.ndarray
    uv: np.ndarray


@dataclass(frozen=True)
class Part:
    """A piece of a shape and how it collides."""

    mesh: MeshData
    """Its triangles (shape frame)."""
    collision: str = "hull"
    """``"hull"``: its convex hull; ``"hollow"``: an open vessel about the z axis through
    ``axis_xy``, collided as floor + wall sectors; ``"none"``: visual only."""
    axis_xy: tuple[float, float] = (0.0, 0.0)
    """Where the vessel's axis is (``"hollow"`` only)."""
    floor: float = 0.0
    """Height of the vessel's inner floor above its lowest point (``"hollow"`` only)."""


def merge(meshes: list[MeshData]) -> MeshData:
    """One mesh of several (vertex indices shifted)."""
    offsets = np.cumsum([0] + [len(m.vertices) for m in meshes])[:-1]
    return MeshData(
        np.concatenate([m.vertices for m in meshes]),
        np.concatenate([m.faces + o for m, o in zip(meshes, offsets)]),
        np.concatenate([m.uv for m in meshes]),
    )


def rotation(axis: str, angle: float) -> np.ndarray:
    """3x3 rotation by ``angle`` radians about ``"x"``, ``"y"`` or ``"z"``."""
    c, s = math.cos(angle), math.sin(angle)
    i, j = {"x": (1, 2), "y": (2, 0), "z": (0, 1)}[axis]
    r = np.eye(3)
    r[i, i], r[i, j], r[j, i], r[j, j] = c, -s, s, c
    return r


def transform(m: MeshData, rot: np.ndarray | None = None, shift=(0.0, 0.0, 0.0), scale=(1.0, 1.0, 1.0)) -> MeshData:
    """``rot @ (scale * v) + shift`` for every vertex; faces flip if the scale mirrors."""
    v = m.vertices * np.asarray(scale, np.float64)
    if rot is not None:
        v = v @ np.asarray(rot, np.float64).T
    faces = m.faces if np.prod(scale) > 0 else m.faces[:, ::-1]
    return MeshData(v + np.asarray(shift, np.float64), faces, m.uv)


def _orient_outward(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Faces reversed if the signed volume of the (closed) mesh is negative."""
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    vol = np.einsum("ij,ij->i", a, np.cross(b, c)).sum()
    return f[:, ::-1] if vol < 0 else f


def revolve(profile_rz, segments: int = 32, phase: float = 0.0) -> MeshData:
    """Surface of revolution of a closed profile about the z axis.

    Args:
        profile_rz: (N, 2) ``(r, z)`` points; a solid's outline from the axis at the bottom
            round to the axis at the top (points on the axis close the ends).
        segments: facets around (6 makes a hexagonal prism).
        phase: angle of the first facet edge (radians).

    Shape:
        returns ``(N * (segments + 1))`` vertices; ``u`` runs round, ``v`` along the profile.
    """
    p = np.asarray(profile_rz, np.float64)
    n = len(p)
    ang = phase + np.linspace(0.0, 2 * math.pi, segments + 1)
    verts = np.stack([
        p[None, :, 0] * np.cos(ang)[:, None], p[None, :, 0] * np.sin(ang)[:, None], np.broadcast_to(p[None, :, 1], (segments + 1, n)),
    ], axis=-1).reshape(-1, 3)
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(p, axis=0).T))])
    uv = np.stack(np.meshgrid(np.linspace(0, 1, segments + 1), arc / max(arc[-1], 1e-12), indexing="ij"), -1).reshape(-1, 2)
    i, j = np.meshgrid(np.arange(segments), np.arange(n - 1), indexing="ij")
    a, b, c, d = i * n + j, (i + 1) * n + j, (i + 1) * n + j + 1, i * n + j + 1
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    tri = verts[faces]
    keep = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1) > 1e-14
    faces = faces[keep]
    return MeshData(verts, _orient_outward(verts, faces), uv)


def cylinder(r: float, h: float, z0: float = 0.0, segments: int = 24, r_top: float | None = None) -> MeshData:
    """A closed (optionally tapered) cylinder standing on ``z0`` about the z axis."""
    rt = r if r_top is None else r_top
    return revolve([(0, z0), (r, z0), (rt, z0 + h), (0, z0 + h)], segments)


def ellipsoid(rx: float, ry: float, rz: float, center=(0.0, 0.0, 0.0), segments: int = 24, rings: int = 12) -> MeshData:
    """An ellipsoid with semi-axes ``rx, ry, rz`` about ``center``."""
    t = np.linspace(-math.pi / 2, math.pi / 2, rings + 1)
    m = revolve(np.stack([np.cos(t), np.sin(t)], 1), segments)
    return transform(m, None, center, (rx, ry, rz))


def box_uv(v: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Split vertices per face and project each face onto the box's plane facing its normal.

    Returns ``(vertices, faces, uv)``, uv scaled by the mesh's bounding box into [0, 1].
    """
    v3 = v[f].reshape(-1, 3)
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    axis = np.repeat(np.argmax(np.abs(n), axis=1), 3)
    lo, hi = v.min(0), v.max(0)
    t = (v3 - lo) / np.maximum(hi - lo, 1e-9)
    uv = np.where(axis[:, None] == 0, t[:, [1, 2]], np.where(axis[:, None] == 1, t[:, [0, 2]], t[:, [0, 1]]))
    return v3, np.arange(len(v3)).reshape(-1, 3), uv


_CUBE_F = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                    [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]])


def box(size, center=(0.0, 0.0, 0.0), rot: np.ndarray | None = None) -> MeshData:
    """An axis-aligned box of ``size`` (x, y, z) about ``center`` (then rotated about it)."""
    sx, sy, sz = (s / 2 for s in size)
    v = np.array([[-sx, -sy, -sz], [sx, -sy, -sz], [sx, sy, -sz], [-sx, sy, -sz],
                  [-sx, -sy, sz], [sx, -sy, sz], [sx, sy, sz], [-sx, sy, sz]], np.float64)
    v3, f3, uv = box_uv(v, _CUBE_F)
    return transform(MeshData(v3, f3, uv), rot, center)


def slab(outline_xy, height: float, z0: float = 0.0) -> MeshData:
    """A prism: a star-shaped outline (counter-clockwise, seen from its centroid) extruded by
    ``height`` from ``z0``; caps are fans about the centroid."""
    p = np.asarray(outline_xy, np.float64)
    n = len(p)
    c = p.mean(0)
    ring = np.concatenate([p, [c]])
    bottom = np.column_stack([ring, np.full(n + 1, z0)])
    top = np.column_stack([ring, np.full(n + 1, z0 + height)])
    v = np.concatenate([bottom, top])
    k = np.arange(n)
    k1 = (k + 1) % n
    top_off = n + 1
    faces = np.concatenate([
        np.stack([np.full(n, n), k1, k], 1),  # bottom fan (facing down)
        np.stack([np.full(n, top_off + n), top_off + k, top_off + k1], 1),
        np.stack([k, k1, top_off + k1], 1), np.stack([k, top_off + k1, top_off + k], 1),
    ])
    v3, f3, uv = box_uv(v, _orient_outward(v, faces))
    return MeshData(v3, f3, uv)


def tube_arc(radius: float, tube: float, a0: float, a1: float, segments: int = 16, sides: int = 10) -> MeshData:
    """A tube of radius ``tube`` along a circular arc of ``radius`` in the x-z plane, from angle
    ``a0`` to ``a1`` (radians, 0 = +x, counter-clockwise towards +z); ends left open (they go
    into the body they join)."""
    t = np.linspace(a0, a1, segments + 1)
    s = np.linspace(0, 2 * math.pi, sides + 1)
    centre = np.stack([radius * np.cos(t), np.zeros_like(t), radius * np.sin(t)], 1)
    out = np.stack([np.cos(t), np.zeros_like(t), np.sin(t)], 1)
    side = np.array([0.0, 1.0, 0.0])
    v = centre[:, None] + tube * (np.cos(s)[None, :, None] * out[:, None] + np.sin(s)[None, :, None] * side)
    v = v.reshape(-1, 3)
    uv = np.stack(np.meshgrid(np.linspace(0, 1, segments + 1), np.linspace(0, 1, sides + 1), indexing="ij"), -1).reshape(-1, 2)
    m = sides + 1
    i, j = np.meshgrid(np.arange(segments), np.arange(sides), indexing="ij")
    a, b, c, d = i * m + j, (i + 1) * m + j, (i + 1) * m + j + 1, i * m + j + 1
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    # outward: the cross of (along arc) x (round the tube) points away from the tube's centre line
    tri = v[faces]
    nrm = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    cen = centre[(faces[:, 0] // m)]
    if np.einsum("ij,ij->i", nrm, tri[:, 0] - cen).sum() < 0:
        faces = faces[:, ::-1]
    return MeshData(v, faces, uv)
