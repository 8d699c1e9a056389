"""Built-in procedural assets: textured objects made of MuJoCo primitives.

Every asset is a function from a size and a material name to MJCF geom elements in the
object's body frame (z up, resting on z = 0), plus a category and default descriptive
phrases. Colours come from textured materials (MuJoCo builtin checker and gradient
textures), so surfaces are not flat colours.

``MESH_ASSETS`` adds object kinds made from the meshes that ship with ``pybullet_data``
(:mod:`sim_envs.assets.meshes`); their geoms refer to mesh assets that a MuJoCo scene declares
with ``mesh_asset_xml``. ``ALL_ASSETS`` holds both; ``ASSETS`` stays the procedural kinds, which
is what the scene generator draws from.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import partial
from typing import Callable

from conceptfusion.errors import UnknownKeyError
from conceptfusion.names import lookup
from sim_envs.assets.meshes import MESH_KINDS, mesh_geoms

__all__ = ["Asset", "ASSETS", "MESH_ASSETS", "ALL_ASSETS", "COLORS", "material_xml", "get_asset"]

COLORS: dict[str, tuple[float, float, float]] = {
    "red": (0.80, 0.12, 0.12),
    "green": (0.16, 0.62, 0.24),
    "blue": (0.12, 0.24, 0.80),
    "yellow": (0.90, 0.82, 0.16),
    "orange": (0.94, 0.51, 0.12),
    "purple": (0.51, 0.20, 0.63),
    "white": (0.92, 0.92, 0.92),
    "black": (0.10, 0.10, 0.10),
    "brown": (0.47, 0.29, 0.16),
    "pink": (0.94, 0.55, 0.75),
}
"""Colour names the generator paints objects with."""


def material_xml(name: str, rgb: tuple[float, float, float], pattern: str = "gradient") -> str:
    """A textured material: a builtin texture whose two colours are shades of ``rgb``."""
    r, g, b = rgb
    lo = f"{r * 0.75:.3f} {g * 0.75:.3f} {b * 0.75:.3f}"
    hi = f"{min(1, r * 1.1):.3f} {min(1, g * 1.1):.3f} {min(1, b * 1.1):.3f}"
    builtin = "checker" if pattern == "checker" else "gradient"
    return (
        f'<texture name="tex_{name}" type="2d" builtin="{builtin}" rgb1="{hi}" rgb2="{lo}" width="64" height="64"/>'
        f'<material name="{name}" texture="tex_{name}" texrepeat="2 2" specular="0.2" shininess="0.2"/>'
    )


@dataclass(frozen=True)
class Asset:
    """A procedural object kind."""

    category: str
    """What it is ("mug", "can", ...)."""
    phrases: tuple[str, ...]
    """Descriptions that hold for every colour ("something to drink from")."""
    default_size: tuple[float, float, float]
    """Bounding box (x, y, z) in metres."""
    geoms: Callable[[tuple[float, float, float], str], str]
    """(size, material) -> MJCF geom elements in the body frame."""
    mesh: str | None = None
    """Key of :data:`sim_envs.assets.meshes.MESH_KINDS` for mesh kinds; None for primitives."""


def _box(size, mat):
    x, y, z = (s / 2 for s in size)
    return f'<geom type="box" size="{x:.4f} {y:.4f} {z:.4f}" pos="0 0 {z:.4f}" material="{mat}"/>'


def _cylinder(size, mat):
    r, h = size[0] / 2, size[2] / 2
    return f'<geom type="cylinder" size="{r:.4f} {h:.4f}" pos="0 0 {h:.4f}" material="{mat}"/>'


def _mug(size, mat):
    r, h = size[1] / 2, size[2] / 2
    handle_x = r + 0.012
    return _cylinder((size[1], size[1], size[2]), mat) + (
        f'<geom type="capsule" fromto="{r:.4f} 0 {h * 1.5:.4f} {handle_x:.4f} 0 {h * 1.1:.4f}" size="0.007" material="{mat}"/>'
        f'<geom type="capsule" fromto="{handle_x:.4f} 0 {h * 1.1:.4f} {r:.4f} 0 {h * 0.5:.4f}" size="0.007" material="{mat}"/>'
    )


def _bottle(size, mat):
    r, h = size[0] / 2, size[2]
    body_h = h * 0.65
    neck_r = r * 0.35
    return (
        f'<geom type="cylinder" size="{r:.4f} {body_h / 2:.4f}" pos="0 0 {body_h / 2:.4f}" material="{mat}"/>'
        f'<geom type="cylinder" size="{neck_r:.4f} {(h - body_h) / 2:.4f}" pos="0 0 {body_h + (h - body_h) / 2:.4f}" material="{mat}"/>'
    )


def _bowl(size, mat):
    r, h = size[0] / 2, size[2]
    parts = [f'<geom type="cylinder" size="{r * 0.6:.4f} 0.005" pos="0 0 0.005" material="{mat}"/>']
    for k in range(8):  # a ring of slanted capsules forms the wall
        a = 2 * math.pi * k / 8
        b = 2 * math.pi * (k + 1) / 8
        parts.append(
            f'<geom type="capsule" fromto="{r * math.cos(a):.4f} {r * math.sin(a):.4f} {h:.4f} '
            f'{r * math.cos(b):.4f} {r * math.sin(b):.4f} {h:.4f}" size="0.008" material="{mat}"/>'
        )
        parts.append(
            f'<geom type="capsule" fromto="{0.6 * r * math.cos(a):.4f} {0.6 * r * math.sin(a):.4f} 0.01 '
            f'{r * math.cos(a):.4f} {r * math.sin(a):.4f} {h:.4f}" size="0.008" material="{mat}"/>'
        )
    return "".join(parts)


def _ball(size, mat):
    r = size[0] / 2
    return f'<geom type="sphere" size="{r:.4f}" pos="0 0 {r:.4f}" material="{mat}"/>'


ASSETS: dict[str, Asset] = {
    "box": Asset("box", ("a cardboard box", "a package"), (0.10, 0.08, 0.08), _box),
    "book": Asset("book", ("a book", "something to read"), (0.15, 0.11, 0.035), _box),
    "can": Asset("can", ("a can of soda", "something to drink"), (0.066, 0.066, 0.12), _cylinder),
    "mug": Asset("mug", ("a coffee mug", "a cup to drink from"), (0.09, 0.08, 0.10), _mug),
    "bottle": Asset("bottle", ("a bottle", "something to drink"), (0.07, 0.07, 0.24), _bottle),
    "bowl": Asset("bowl", ("a bowl", "a dish for food"), (0.16, 0.16, 0.06), _bowl),
    "ball": Asset("ball", ("a ball", "a toy to play with"), (0.09, 0.09, 0.09), _ball),
}
"""Built-in procedural assets by name."""

MESH_ASSETS: dict[str, Asset] = {
    name: Asset(k.category, k.phrases, k.default_size, partial(mesh_geoms, name), mesh=name)
    for name, k in MESH_KINDS.items()
}
"""Mesh object kinds from ``pybullet_data`` by name (see :mod:`sim_envs.assets.meshes`)."""

ALL_ASSETS: dict[str, Asset] = {**ASSETS, **MESH_ASSETS}
"""Every object kind a scene may use: procedural and mesh."""


def get_asset(name: str) -> Asset:
    """The asset called ``name`` (procedural or mesh); ``KeyError`` naming the nearest names."""
    return lookup(ALL_ASSETS, name, "asset", cutoff=0.6, listing=f"known: {', '.join(sorted(ALL_ASSETS))}",
                  error=UnknownKeyError)
