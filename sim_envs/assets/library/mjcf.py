"""Library instances in MuJoCo: ``<asset>`` children and the geoms of an object's body.

A mesh's scale is fixed in ``<asset>``, so a scene declares one set of meshes per distinct
``(instance, size)`` (:func:`library_asset_xml`) and its bodies refer to them
(:func:`library_geoms`). The visual geom draws the textured mesh and neither collides nor weighs;
the convex pieces collide, carry the mass, and sit in geom group 3, which renderers hide.
"""

from __future__ import annotations

from typing import Iterable

from sim_envs.assets.library.catalogue import Instance, get_instance
from sim_envs.assets.library.export import export_instance
from sim_envs.assets.library.palette import MATERIALS

__all__ = ["library_asset_xml", "library_geoms", "library_mesh_prefix", "COLLISION_GROUP"]

COLLISION_GROUP = 3
"""Geom group of the collision pieces (hidden by default in MuJoCo's renderers)."""


def _size(inst: Instance, size) -> tuple[float, float, float]:
    if size is None:
        return export_instance(inst).size
    s = tuple(float(x) for x in size)
    if len(s) != 3 or min(s) <= 0:
        raise ValueError(f"library instance {inst.id!r}: expected a positive (x, y, z) size, got {size}")
    return s


def library_mesh_prefix(instance: str, size) -> str:
    """Stem of the MJCF mesh names of ``instance`` (id or ``lib:`` asset) at ``size``."""
    inst = get_instance(instance)
    sx, sy, sz = _size(inst, size)
    return f"lib_{inst.id}_{round(sx * 1e4)}_{round(sy * 1e4)}_{round(sz * 1e4)}"


def library_asset_xml(items: Iterable) -> str:
    """The ``<asset>`` children for library objects.

    Args:
        items: instance ids / ``lib:`` asset names (own size) or ``(id, size)`` pairs; duplicates
            are declared once.

    Returns:
        MJCF text: per distinct (instance, size) a visual ``<mesh>`` and one ``<mesh>`` per
        convex piece; per instance a ``<texture>`` and a ``<material>``. Paths are absolute.
    """
    meshes: dict[str, str] = {}
    materials: dict[str, str] = {}
    for item in items:
        name, size = (item, None) if isinstance(item, str) else (item[0], item[1])
        inst = get_instance(name)
        exp = export_instance(inst)
        s = _size(inst, size)
        prefix = library_mesh_prefix(inst.id, s)
        scale = f"{s[0]:.5f} {s[1]:.5f} {s[2]:.5f}"
        if prefix not in meshes:
            parts = [f'<mesh name="{prefix}_vis" file="{exp.visual}" scale="{scale}"/>']
            parts += [f'<mesh name="{prefix}_h{k}" file="{h}" scale="{scale}"/>' for k, h in enumerate(exp.hulls)]
            meshes[prefix] = "".join(parts)
        if inst.id not in materials:
            look = MATERIALS[inst.material]
            materials[inst.id] = (
                f'<texture name="tex_lib_{inst.id}" type="2d" file="{exp.texture}"/>'
                f'<material name="mat_lib_{inst.id}" texture="tex_lib_{inst.id}" specular="{look.specular}" shininess="{look.shininess}"/>'
            )
    return "".join(meshes.values()) + "".join(materials.values())


def library_geoms(instance: str, size=None) -> str:
    """MJCF geoms of a library object in its body frame (z up, resting on z = 0); the meshes
    and material must be declared with :func:`library_asset_xml`."""
    inst = get_instance(instance)
    exp = export_instance(inst)
    prefix = library_mesh_prefix(inst.id, _size(inst, size))
    geoms = [f'<geom type="mesh" mesh="{prefix}_vis" material="mat_lib_{inst.id}" contype="0" conaffinity="0" density="0"/>']
    geoms += [
        f'<geom type="mesh" mesh="{prefix}_h{k}" group="{COLLISION_GROUP}" rgba="0.5 0.5 0.5 0" density="300"/>'
        for k in range(len(exp.hulls))
    ]
    return "".join(geoms)
