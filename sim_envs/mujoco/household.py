"""MJCF of the household parts of a scene: room floors, walls with door gaps, furniture bodies."""

from __future__ import annotations

import math

from sim_envs.assets.furniture import FURNITURE, material_name, materials_xml

__all__ = ["household_assets_xml", "household_body_xml", "LINTEL_HEIGHT"]

LINTEL_HEIGHT = 2.1
"""Height of the top of a door opening (metres); the wall above it is solid."""


def household_assets_xml() -> str:
    """Textures and materials of furniture, walls and floors."""
    return materials_xml()


def _wall_box(name: str, cx: float, cy: float, yaw: float, half_len: float, half_t: float, z0: float, z1: float, mat: str) -> str:
    return (
        f'<geom name="{name}" type="box" pos="{cx:.4f} {cy:.4f} {(z0 + z1) / 2:.4f}" euler="0 0 {yaw:.6f}" '
        f'size="{half_len:.4f} {half_t:.4f} {(z1 - z0) / 2:.4f}" material="{material_name(mat)}"/>'
    )


def household_body_xml(scene) -> str:
    """World-body elements: directional lights, a ground plane, one floor slab per room, walls
    (two half-thickness slabs, one per face material; doors are gaps with a lintel above) and
    one static body per piece of furniture, named by its id.
    """
    parts = [
        '<light directional="true" dir="-0.3 0.4 -1" diffuse="0.45 0.45 0.43" specular="0.1 0.1 0.1" castshadow="false"/>',
        '<light directional="true" dir="0.6 -0.3 -0.6" diffuse="0.25 0.25 0.26" specular="0 0 0" castshadow="false"/>',
        '<light directional="true" dir="-0.6 -0.5 -0.5" diffuse="0.2 0.2 0.2" specular="0 0 0" castshadow="false"/>',
        '<light directional="true" dir="0.4 0.7 -0.5" diffuse="0.2 0.2 0.2" specular="0 0 0" castshadow="false"/>',
        f'<geom name="ground" type="plane" pos="0 0 -0.02" size="{_ground_half(scene):.1f} {_ground_half(scene):.1f} 2" material="{material_name("ground")}"/>',
    ]
    for r in scene.rooms:
        (x0, y0), (x1, y1) = r.floor
        parts.append(
            f'<geom name="{r.id}_floor" type="box" pos="{(x0 + x1) / 2:.4f} {(y0 + y1) / 2:.4f} -0.01" '
            f'size="{(x1 - x0) / 2:.4f} {(y1 - y0) / 2:.4f} 0.01" material="{material_name(r.floor_material)}"/>'
        )
    for w in scene.walls:
        (sx, sy), (ex, ey) = w.start, w.end
        ux, uy = (ex - sx) / w.length, (ey - sy) / w.length
        nx, ny = -uy, ux  # left normal
        yaw = math.atan2(uy, ux)
        q = w.thickness / 4
        pieces = [(a, b, 0.0, w.height) for a, b in w.solid_spans()]
        pieces += [(off, off + width, LINTEL_HEIGHT, w.height) for off, width in w.doors if w.height > LINTEL_HEIGHT]
        for k, (a, b, z0, z1) in enumerate(pieces):
            m = (a + b) / 2
            cx, cy = sx + ux * m, sy + uy * m
            for side, sign, mat in (("l", 1, w.materials[0]), ("r", -1, w.materials[1])):
                parts.append(_wall_box(f"{w.id}_{k}{side}", cx + sign * nx * q, cy + sign * ny * q, yaw, (b - a) / 2, q, z0, z1, mat))
    for f in scene.furniture:
        x, y, z = f.position
        geoms = FURNITURE[f.category].geoms(f.size, f.material, f.shelf_heights)
        parts.append(f'<body name="{f.id}" pos="{x} {y} {z}" euler="0 0 {f.yaw}">{geoms}</body>')
    return "".join(parts)


def _ground_half(scene) -> float:
    ext = max(max(abs(v) for r in scene.rooms for corner in r.floor for v in corner), 5.0)
    return ext + 5.0
