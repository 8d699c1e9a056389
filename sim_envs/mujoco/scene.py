"""Building a :class:`~sim_envs.scenes.format.Scene` in MuJoCo (MJCF)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim_envs import headless  # noqa: F401

import mujoco  # noqa: E402

from sim_envs.assets.objects import ALL_ASSETS, COLORS, MESH_ASSETS, material_xml  # noqa: E402
from sim_envs.assets.meshes import mesh_asset_xml  # noqa: E402
from sim_envs.assets.library.catalogue import is_library_asset  # noqa: E402
from sim_envs.assets.library.mjcf import library_asset_xml, library_geoms  # noqa: E402
from sim_envs.mujoco.household import household_assets_xml, household_body_xml  # noqa: E402
from sim_envs.scenes.format import Scene  # noqa: E402

__all__ = ["MujocoScene", "build_mjcf", "build_mujoco", "split_labels"]


@dataclass
class MujocoScene:
    """A scene loaded in MuJoCo.

    ``geom_object[g]`` is the index into ``scene.objects`` of geom ``g`` (-1 for the room,
    table, line, walls, floors and furniture); ``object_body[i]`` the body id of object ``i``;
    ``geom_furniture[g]`` the index into ``scene.furniture`` of geom ``g`` (-1 elsewhere).

    Shape:
        ``geom_object``, ``geom_furniture`` (ngeom,) int32; ``object_body`` (num_objects,) int32.
    """

    scene: Scene
    model: mujoco.MjModel
    data: mujoco.MjData
    geom_object: np.ndarray
    object_body: np.ndarray
    geom_furniture: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.geom_furniture is None:
            self.geom_furniture = np.full(self.model.ngeom, -1, np.int32)

    def geom_labels(self) -> np.ndarray:
        """One label per geom for a single segmentation pass: object ``i`` -> ``i``, furniture
        ``j`` -> ``num_objects + j``, anything else -1; undo with :func:`split_labels`.

        Shape:
            returns (ngeom,) int32.
        """
        n = len(self.scene.objects)
        return np.where(self.geom_object >= 0, self.geom_object, np.where(self.geom_furniture >= 0, self.geom_furniture + n, -1)).astype(np.int32)


def split_labels(labels_hw: np.ndarray, num_objects: int) -> tuple[np.ndarray, np.ndarray]:
    """Object and furniture index images from a segmentation of :meth:`MujocoScene.geom_labels`.

    Shape:
        ``labels_hw`` (H, W) int; returns two (H, W) int32 images, -1 where none.
    """
    labels_hw = np.asarray(labels_hw)
    objects = np.where((labels_hw >= 0) & (labels_hw < num_objects), labels_hw, -1).astype(np.int32)
    furniture = np.where(labels_hw >= num_objects, labels_hw - num_objects, -1).astype(np.int32)
    return objects, furniture


def build_mjcf(scene: Scene) -> str:
    """MJCF text of a scene: one free body per object, and either the tabletop (textured floor,
    table, dividing line) or the household (room floors, walls, static furniture bodies).

    Rendering quality is set for speed on a software rasteriser: no multisampling, coarse
    tessellation of round primitives (12 slices, 6 stacks), no shadows.
    """
    mats = [
        material_xml("floor", (0.55, 0.55, 0.58), "checker"),
        material_xml("wood", (0.55, 0.36, 0.20)),
        material_xml("line", (0.95, 0.85, 0.10)),
    ]
    for c, rgb in sorted(COLORS.items()):
        mats.append(material_xml(f"paint_{c}", rgb))
    meshes = [(o.asset, o.size) for o in scene.objects if o.asset in MESH_ASSETS]
    if meshes:
        mats.append(mesh_asset_xml(meshes))
    library = [(o.asset, o.size) for o in scene.objects if is_library_asset(o.asset)]
    if library:
        mats.append(library_asset_xml(library))
    # Shadow maps dominate software rendering (10x); lights cast none.
    if scene.is_household:
        mats.append(household_assets_xml())
        body = [household_body_xml(scene)]
    else:
        body = ['<light pos="0 0 3" dir="0 0 -1" diffuse="0.8 0.8 0.8" castshadow="false"/>', '<light pos="2 -2 3" dir="-1 1 -1.5" diffuse="0.4 0.4 0.4" castshadow="false"/>']
        body.append('<geom name="floor" type="plane" size="5 5 0.1" material="floor"/>')
    if scene.table is not None:
        t = scene.table
        cx, cy, cz = t.center
        sx, sy, sz = (s / 2 for s in t.size)
        body.append(f'<geom name="table_top" type="box" pos="{cx} {cy} {cz}" size="{sx} {sy} {sz}" material="wood"/>')
        for i, (lx, ly) in enumerate([(1, 1), (1, -1), (-1, 1), (-1, -1)]):
            leg_h = (cz - sz) / 2
            body.append(
                f'<geom name="table_leg{i}" type="box" pos="{cx + lx * (sx - 0.04)} {cy + ly * (sy - 0.04)} {leg_h}" '
                f'size="0.025 0.025 {leg_h}" material="wood"/>'
            )
        if scene.line is not None:
            (x0, y0), (x1, y1) = scene.line
            body.append(
                f'<geom name="line" type="box" pos="{(x0 + x1) / 2} {(y0 + y1) / 2} {t.top_z + 0.0005}" '
                f'size="0.008 {abs(y1 - y0) / 2} 0.0005" material="line" contype="0" conaffinity="0"/>'
            )
    for o in scene.objects:
        if is_library_asset(o.asset):
            geoms = library_geoms(o.asset, o.size)
        else:
            geoms = ALL_ASSETS[o.asset].geoms(o.size, f"paint_{o.color}")
        x, y, z = o.position
        body.append(
            f'<body name="{o.id}" pos="{x} {y} {z + 0.001}" euler="0 0 {o.yaw}"><freejoint name="{o.id}_joint"/>'
            f"{geoms}</body>"
        )
    return (
        f'<mujoco model="{scene.id}"><compiler angle="radian"/><option timestep="0.002"/>'
        '<visual><quality offsamples="0" numslices="12" numstacks="6" numquads="1"/><map znear="0.01" zfar="50"/></visual>'
        f"<asset>{''.join(mats)}</asset><worldbody>{''.join(body)}</worldbody></mujoco>"
    )


def build_mujoco(scene: Scene) -> MujocoScene:
    """Compile a scene into a model and data, settled with one forward pass."""
    model = mujoco.MjModel.from_xml_string(build_mjcf(scene))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    body_object = np.full(model.nbody, -1, np.int32)
    object_body = np.empty(len(scene.objects), np.int32)
    for i, o in enumerate(scene.objects):
        b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, o.id)
        body_object[b] = i
        object_body[i] = b
    geom_object = body_object[model.geom_bodyid]
    body_furniture = np.full(model.nbody, -1, np.int32)
    for j, f in enumerate(scene.furniture):
        body_furniture[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f.id)] = j
    return MujocoScene(scene, model, data, geom_object, object_body, body_furniture[model.geom_bodyid])
