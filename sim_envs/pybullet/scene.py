"""Building a :class:`~sim_envs.scenes.format.Scene` in a PyBullet physics client.

Objects get the same shapes as in MuJoCo: procedural kinds are read from the MJCF geoms of
:mod:`sim_envs.assets.objects` (boxes, cylinders, capsules, spheres become one compound body), mesh
kinds load the normalised meshes of :mod:`sim_envs.assets.meshes`, object library instances
(``"lib:<id>"``) their URDF (:mod:`sim_envs.assets.library.urdf`). Surfaces carry textures
(gradients and checkers in the object's colour, written as small PNGs into the asset cache),
not flat colours.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from sim_envs.assets.objects import COLORS, get_asset
from sim_envs.assets.meshes import mesh_texture, normalized_mesh
from sim_envs.assets.library.catalogue import is_library_asset
from sim_envs.assets.library.urdf import instance_urdf, load_instance
from conceptfusion.errors import SceneFormatError
from sim_envs.scenes.format import Scene, SceneObject
from sim_envs.pybullet.shapes import compound_shapes, primitive_shapes, texture_png

__all__ = ["PyBulletScene", "build_pybullet", "OBJECT_FRICTION"]

OBJECT_FRICTION = 0.5
"""Lateral friction of objects and table top (a box pushed over wood)."""

_DENSITY = 400.0  # kg/m^3 of the bounding box, clipped to 0.1-0.5 kg


@dataclass
class PyBulletScene:
    """A scene loaded in a PyBullet client.

    ``object_body[i]`` is the body id of ``scene.objects[i]``; ``body_object`` maps body ids
    to object indices (bodies that are no object map to -1 through :meth:`body_lut`).
    """

    scene: Scene
    client: int
    object_body: np.ndarray
    body_object: dict[int, int]
    table_body: int | None
    line_body: int | None
    floor_body: int
    body_furniture: dict[int, int] = field(default_factory=dict)
    """Body id -> index into ``scene.furniture`` (household scenes; a piece may have several bodies)."""
    furniture_shapes: list = field(default_factory=list)
    """Per piece of furniture, its shapes in the piece's frame (household scenes)."""

    def body_lut(self, n_bodies: int | None = None) -> np.ndarray:
        """(B,) int32 lookup from body id to object index, -1 elsewhere."""
        import pybullet as p

        n = p.getNumBodies(physicsClientId=self.client) if n_bodies is None else n_bodies
        lut = np.full(max(n, max(self.body_object, default=-1) + 1), -1, np.int32)
        for b, i in self.body_object.items():
            lut[b] = i
        return lut

    def body_labels(self) -> np.ndarray:
        """(B,) int32 lookup for one segmentation pass, as MuJoCo's ``geom_labels``: object ``i``
        -> ``i``, furniture ``j`` -> ``num_objects + j``, anything else -1 (undo with
        :func:`sim_envs.mujoco.scene.split_labels`)."""
        lut = self.body_lut(max(max(self.body_furniture, default=-1) + 1, len(self.body_object)))
        n = len(self.scene.objects)
        for b, j in self.body_furniture.items():
            lut[b] = n + j
        return lut

    def object_aabbs(self) -> np.ndarray:
        """World axis-aligned box around each object's size box in its current pose.

        Shape:
            returns (num_objects, 2, 3): ``[i, 0]`` lower corner, ``[i, 1]`` upper corner.
        """
        import pybullet as p

        out = np.empty((len(self.scene.objects), 2, 3))
        for i, (o, b) in enumerate(zip(self.scene.objects, self.object_body)):
            com_pos, com_orn = p.getBasePositionAndOrientation(int(b), physicsClientId=self.client)
            info = p.getDynamicsInfo(int(b), -1, physicsClientId=self.client)
            pos, orn = p.multiplyTransforms(com_pos, com_orn, *p.invertTransform(info[3], info[4]))
            sx, sy, sz = o.size
            corners = np.array([[x, y, z] for x in (-sx / 2, sx / 2) for y in (-sy / 2, sy / 2) for z in (0.0, sz)])
            world = corners @ np.asarray(p.getMatrixFromQuaternion(orn)).reshape(3, 3).T + pos
            out[i, 0], out[i, 1] = world.min(0), world.max(0)
        return out

    def furniture_aabbs(self) -> np.ndarray:
        """World axis-aligned box of every piece of furniture (static: from its shapes and pose).

        Shape:
            returns (num_furniture, 2, 3).
        """
        from sim_envs.pybullet.household import furniture_aabbs

        return furniture_aabbs(self.scene, self.furniture_shapes)


def _object_body(o: SceneObject, client: int, where: str) -> int:
    import pybullet as p

    if is_library_asset(o.asset):  # object library instance: its URDF (textured mesh, convex pieces)
        x, y, z = o.position
        try:
            body = load_instance(o.asset, client, (x, y, z + 0.001), o.yaw, o.size)
        except p.error as exc:  # checked files should load; name what did not
            raise SceneFormatError(f"{where} ({o.asset!r}): PyBullet could not load {instance_urdf(o.asset, o.size)}: {exc}") from None
        p.changeDynamics(
            body, -1, lateralFriction=OBJECT_FRICTION, spinningFriction=0.001, rollingFriction=0.0001,
            linearDamping=0.04, angularDamping=0.04, physicsClientId=client,
        )
        return body
    asset = get_asset(o.asset)
    size = tuple(float(s) for s in o.size)
    if asset.mesh is not None:
        path = str(normalized_mesh(asset.mesh))
        col = p.createCollisionShape(p.GEOM_MESH, fileName=path, meshScale=size, physicsClientId=client)
        vis = p.createVisualShape(p.GEOM_MESH, fileName=path, meshScale=size, physicsClientId=client)
        tex_path = mesh_texture(asset.mesh)
    else:
        col, vis = compound_shapes(primitive_shapes(o.asset, size), client)
        tex_path = None
    if tex_path is None:
        tex_path = texture_png(f"paint_{o.color}", COLORS[o.color], "gradient")
    mass = float(np.clip(_DENSITY * size[0] * size[1] * size[2], 0.1, 0.5))
    quat = p.getQuaternionFromEuler([0.0, 0.0, o.yaw])
    x, y, z = o.position
    body = p.createMultiBody(
        baseMass=mass, baseCollisionShapeIndex=col, baseVisualShapeIndex=vis,
        basePosition=[x, y, z + 0.001], baseOrientation=quat,
        baseInertialFramePosition=[0.0, 0.0, size[2] * 0.4], physicsClientId=client,
    )
    tex = p.loadTexture(str(tex_path), physicsClientId=client)
    p.changeVisualShape(body, -1, textureUniqueId=tex, rgbaColor=[1, 1, 1, 1], physicsClientId=client)
    p.changeDynamics(
        body, -1, lateralFriction=OBJECT_FRICTION, spinningFriction=0.001, rollingFriction=0.0001,
        linearDamping=0.04, angularDamping=0.04, physicsClientId=client,
    )
    return body


def _static_body(shapes: list[dict], texture: str, client: int, *, collide: bool = True) -> int:
    import pybullet as p

    col, vis = compound_shapes(shapes, client)
    body = p.createMultiBody(0.0, col if collide else -1, vis, physicsClientId=client)
    p.changeVisualShape(body, -1, textureUniqueId=p.loadTexture(texture, physicsClientId=client), physicsClientId=client)
    p.changeDynamics(body, -1, lateralFriction=OBJECT_FRICTION, physicsClientId=client)
    return body


def build_pybullet(scene: Scene, client: int, *, source: str | None = None) -> PyBulletScene:
    """Load ``scene`` into the PyBullet client ``client`` (gravity -9.81 z).

    A tabletop: floor (checker), table top with four legs (wood), the dividing line (visual only,
    no collision). A household: ground, room floors, walls and furniture
    (:func:`sim_envs.pybullet.household.build_household`). Then one dynamic body per object,
    placed 1 mm above its resting height.

    Every asset is checked first (:func:`~sim_envs.pybullet.asset_checks.check_pybullet_assets`):
    a scene PyBullet cannot build raises :class:`~conceptfusion.errors.SceneFormatError` naming
    ``source`` (default: the scene id), the field and the file, with nothing loaded.
    """
    import pybullet as p

    from sim_envs.pybullet.asset_checks import check_pybullet_assets
    from sim_envs.pybullet.household import build_household

    furniture = check_pybullet_assets(scene, source)
    p.setGravity(0.0, 0.0, -9.81, physicsClientId=client)
    box = p.GEOM_BOX
    body_furniture: dict[int, int] = {}
    if scene.is_household:
        house = build_household(scene, client, furniture)
        floor, body_furniture = house.static[0], house.body_furniture
    else:
        floor = _static_body(
            [{"shapeType": box, "halfExtents": [5, 5, 0.05], "pos": [0, 0, -0.05], "quat": [0, 0, 0, 1]}],
            texture_png("floor", (0.55, 0.55, 0.58), "checker", 128), client,
        )
    table_body = line_body = None
    if scene.table is not None:
        t = scene.table
        cx, cy, cz = t.center
        sx, sy, sz = (s / 2 for s in t.size)
        leg_h = (cz - sz) / 2
        shapes = [{"shapeType": box, "halfExtents": [sx, sy, sz], "pos": [0, 0, 0], "quat": [0, 0, 0, 1]}]
        for lx, ly in [(1, 1), (1, -1), (-1, 1), (-1, -1)]:
            shapes.append({
                "shapeType": box, "halfExtents": [0.025, 0.025, leg_h],
                "pos": [lx * (sx - 0.04), ly * (sy - 0.04), leg_h - cz], "quat": [0, 0, 0, 1],
            })
        table_body = _static_body(shapes, texture_png("wood", (0.55, 0.36, 0.20)), client)
        p.resetBasePositionAndOrientation(table_body, [cx, cy, cz], [0, 0, 0, 1], physicsClientId=client)
        if scene.line is not None:
            (x0, y0), (x1, y1) = scene.line
            length = math.hypot(x1 - x0, y1 - y0)
            yaw = math.atan2(y1 - y0, x1 - x0)
            line_body = _static_body(
                [{"shapeType": box, "halfExtents": [length / 2, 0.008, 0.0005], "pos": [0, 0, 0], "quat": [0, 0, 0, 1]}],
                texture_png("line", (0.95, 0.85, 0.10)), client, collide=False,
            )
            p.resetBasePositionAndOrientation(
                line_body, [(x0 + x1) / 2, (y0 + y1) / 2, t.top_z + 0.0005],
                p.getQuaternionFromEuler([0, 0, yaw]), physicsClientId=client,
            )
    bodies = np.array([_object_body(o, client, f"{source or f'scene {scene.id!r}'}: objects[{i}].asset") for i, o in enumerate(scene.objects)],
                      np.int64)
    return PyBulletScene(
        scene=scene, client=client, object_body=bodies, body_object={int(b): i for i, b in enumerate(bodies)},
        table_body=table_body, line_body=line_body, floor_body=floor, body_furniture=body_furniture,
        furniture_shapes=furniture,
    )
