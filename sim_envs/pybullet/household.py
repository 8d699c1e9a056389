"""The household parts of a scene in PyBullet: ground, room floors, walls with door gaps and
lintels, furniture, from the same descriptions MuJoCo builds them from.

Walls come from :func:`sim_envs.scenes.household_shapes.wall_boxes` and furniture from the MJCF geoms of
:data:`sim_envs.assets.furniture.FURNITURE` (read by :func:`~sim_envs.pybullet.scene.mjcf_shapes`),
so the two simulators hold the same boxes. Ground and floors match
:func:`sim_envs.mujoco.household.household_body_xml`: a ground slab whose top is 2 cm below the
floor, one 2 cm floor slab per room with its top at z = 0. A piece of furniture is one static
compound body per material it uses (PyBullet textures a body, not a shape), all of them mapping
to the piece's index. Textures are two-shade PNGs in each material's colours
(:func:`~sim_envs.assets.furniture.material_look`): the same colours as MuJoCo's, not the same
pixels.
"""

from __future__ import annotations

import math

import numpy as np

from sim_envs.assets.furniture import FURNITURE, MATERIALS, material_look, material_name
from sim_envs.pybullet.shapes import compound_shapes, mjcf_shapes, texture_png
from sim_envs.scenes.household_shapes import ground_half, wall_boxes

__all__ = ["HouseholdBodies", "build_household", "furniture_shapes"]

_MAT_BY_MJCF = {material_name(m): m for m in MATERIALS}


class HouseholdBodies:
    """Body ids of what :func:`build_household` loaded.

    ``body_furniture`` maps every body of a piece of furniture to its index in
    ``scene.furniture``; ``static`` lists every body (ground, floors, walls, furniture).
    """

    def __init__(self) -> None:
        self.body_furniture: dict[int, int] = {}
        self.static: list[int] = []


def furniture_shapes(scene) -> list[list[dict]]:
    """Per piece of furniture, its shapes (:func:`~sim_envs.pybullet.scene.mjcf_shapes`) in the
    piece's frame, each with its ``material`` (a name of :data:`MATERIALS`). A shape PyBullet
    cannot build raises ``ValueError`` naming ``furniture[j]``."""
    out = []
    for j, f in enumerate(scene.furniture):
        shapes = mjcf_shapes(FURNITURE[f.category].geoms(f.size, f.material, f.shelf_heights), f"furniture[{j}] ({f.id!r}, {f.category})")
        for s in shapes:
            s["material"] = _MAT_BY_MJCF.get(s["material"], f.material)
        out.append(shapes)
    return out


def _texture(material: str, client: int, cache: dict) -> int:
    import pybullet as p

    if material not in cache:
        builtin, rgb1, _ = material_look(material)
        path = texture_png(f"hm_{material}", rgb1, "checker" if builtin == "checker" else "gradient")
        cache[material] = p.loadTexture(path, physicsClientId=client)
    return cache[material]


def _static(shapes: list[dict], position, yaw: float, texture: int, client: int) -> int:
    import pybullet as p

    col, vis = compound_shapes(shapes, client)
    body = p.createMultiBody(0.0, col, vis, basePosition=[float(v) for v in position],
                             baseOrientation=p.getQuaternionFromEuler([0.0, 0.0, float(yaw)]), physicsClientId=client)
    p.changeVisualShape(body, -1, textureUniqueId=texture, rgbaColor=[1, 1, 1, 1], physicsClientId=client)
    return body


def _box(half, pos=(0.0, 0.0, 0.0)) -> dict:
    import pybullet as p

    return {"shapeType": p.GEOM_BOX, "halfExtents": [float(h) for h in half], "pos": [float(v) for v in pos], "quat": [0.0, 0.0, 0.0, 1.0]}


def build_household(scene, client: int, furniture: list[list[dict]] | None = None) -> HouseholdBodies:
    """Load ground, floors, walls and furniture of household ``scene`` into ``client`` as static
    bodies; ``furniture`` is :func:`furniture_shapes` of the scene when already computed."""
    out = HouseholdBodies()
    textures: dict[str, int] = {}
    g = ground_half(scene)
    out.static.append(_static([_box((g, g, 0.01))], (0.0, 0.0, -0.03), 0.0, _texture("ground", client, textures), client))
    for r in scene.rooms:
        (x0, y0), (x1, y1) = r.floor
        body = _static([_box(((x1 - x0) / 2, (y1 - y0) / 2, 0.01))], ((x0 + x1) / 2, (y0 + y1) / 2, -0.01), 0.0,
                       _texture(r.floor_material, client, textures), client)
        out.static.append(body)
    for w in scene.walls:
        for b in wall_boxes(w):
            out.static.append(_static([_box(b.half)], b.centre, b.yaw, _texture(b.material, client, textures), client))
    shapes_all = furniture_shapes(scene) if furniture is None else furniture
    for j, (f, shapes) in enumerate(zip(scene.furniture, shapes_all)):
        by_material: dict[str, list[dict]] = {}
        for s in shapes:
            by_material.setdefault(s["material"], []).append(s)
        for mat, group in by_material.items():
            body = _static(group, f.position, f.yaw, _texture(mat, client, textures), client)
            out.body_furniture[body] = j
            out.static.append(body)
    return out


def furniture_aabbs(scene, furniture: list[list[dict]]) -> np.ndarray:
    """World axis-aligned box of every piece from its shapes and pose (furniture never moves).

    Shape:
        returns (num_furniture, 2, 3).
    """
    out = np.empty((len(scene.furniture), 2, 3))
    for j, (f, shapes) in enumerate(zip(scene.furniture, furniture)):
        c, s = math.cos(f.yaw), math.sin(f.yaw)
        R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        pts = []
        for sh in shapes:
            half = np.asarray(sh["halfExtents"], np.float64)  # furniture is boxes only
            corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * half + sh["pos"]
            pts.append(corners @ R.T + np.asarray(f.position, np.float64))
        pts = np.concatenate(pts)
        out[j, 0], out[j, 1] = pts.min(0), pts.max(0)
    return out
