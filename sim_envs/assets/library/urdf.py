"""Library instances in PyBullet: a URDF per (instance, size) and a loader.

The URDF's one link draws the textured visual OBJ and collides with the convex pieces of
:mod:`~sim_envs.assets.library.export` (PyBullet turns several ``<collision>`` meshes into one
compound of convex hulls). Mass follows the scene builder's rule for objects (400 kg/m^3 of the
bounding box, clipped to 0.1-0.5 kg) with the inertial frame 40% up the object, as for the other
objects; :func:`load_instance` applies the texture, which PyBullet does not read from a URDF.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np

from conceptfusion.io_utils import atomic_write_text
from sim_envs.assets.library.catalogue import get_instance
from sim_envs.assets.library.export import export_instance
from sim_envs.assets.meshes import cache_dir

__all__ = ["instance_urdf", "load_instance", "object_mass"]

_DENSITY = 400.0


def object_mass(size) -> float:
    """Mass (kg) of an object whose bounding box is ``size``: 400 kg/m^3, clipped to 0.1-0.5 kg."""
    return float(np.clip(_DENSITY * size[0] * size[1] * size[2], 0.1, 0.5))


def instance_urdf(instance: str, size=None) -> Path:
    """Path of the URDF of ``instance`` (id or ``lib:`` asset) scaled to ``size`` (x, y, z
    metres; None: its own size), written into the asset cache on first use."""
    inst = get_instance(instance)
    exp = export_instance(inst)
    s = exp.size if size is None else tuple(float(x) for x in size)
    if len(s) != 3 or min(s) <= 0:
        raise ValueError(f"library instance {inst.id!r}: expected a positive (x, y, z) size, got {size}")
    key = hashlib.sha1(f"{exp.visual}|{s}".encode()).hexdigest()[:10]
    out = cache_dir() / "library" / "urdf" / f"{inst.id}_{key}.urdf"
    if out.exists():
        return out
    scale = f"{s[0]:.5f} {s[1]:.5f} {s[2]:.5f}"
    m = object_mass(s)
    ixx = m * (s[1] ** 2 + s[2] ** 2) / 12
    iyy = m * (s[0] ** 2 + s[2] ** 2) / 12
    izz = m * (s[0] ** 2 + s[1] ** 2) / 12
    cols = "".join(
        f'<collision><origin xyz="0 0 0"/><geometry><mesh filename="{h}" scale="{scale}"/></geometry></collision>' for h in exp.hulls
    )
    text = (
        f'<?xml version="1.0"?>\n<robot name="{inst.id}"><link name="base">'
        f'<inertial><origin xyz="0 0 {s[2] * 0.4:.5f}"/><mass value="{m:.5f}"/>'
        f'<inertia ixx="{ixx:.3e}" ixy="0" ixz="0" iyy="{iyy:.3e}" iyz="0" izz="{izz:.3e}"/></inertial>'
        f'<visual><origin xyz="0 0 0"/><geometry><mesh filename="{exp.visual}" scale="{scale}"/></geometry></visual>'
        f"{cols}</link></robot>\n"
    )
    atomic_write_text(out, text)
    return out


def load_instance(instance: str, client: int, position=(0.0, 0.0, 0.0), yaw: float = 0.0, size=None) -> int:
    """Load ``instance`` into PyBullet client ``client`` as a dynamic body, textured; returns
    the body id. ``position`` is the centre of its base (metres)."""
    import pybullet as p

    inst = get_instance(instance)
    exp = export_instance(inst)
    body = p.loadURDF(
        str(instance_urdf(inst.id, size)), basePosition=[float(x) for x in position],
        baseOrientation=p.getQuaternionFromEuler([0.0, 0.0, float(yaw)]),
        flags=p.URDF_USE_INERTIA_FROM_FILE, physicsClientId=client,
    )
    tex = p.loadTexture(str(exp.texture), physicsClientId=client)
    p.changeVisualShape(body, -1, textureUniqueId=tex, rgbaColor=[1, 1, 1, 1], physicsClientId=client)
    return body
