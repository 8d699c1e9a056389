"""MJCF of the household parts of a scene: room floors, walls with door gaps, furniture bodies."""

from __future__ import annotations

from sim_envs.assets.furniture import FURNITURE, material_name, materials_xml
from sim_envs.scenes.household_shapes import LINTEL_HEIGHT, ground_half, wall_boxes

__all__ = ["household_assets_xml", "household_body_xml", "LINTEL_HEIGHT"]


def household_assets_xml() -> str:
    """Textures and materials of furniture, walls and floors."""
    return materials_xml()


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
        f'<geom name="ground" type="plane" pos="0 0 -0.02" size="{ground_half(scene):.1f} {ground_half(scene):.1f} 2" material="{material_name("ground")}"/>',
    ]
    for r in scene.rooms:
        (x0, y0), (x1, y1) = r.floor
        parts.append(
            f'<geom name="{r.id}_floor" type="box" pos="{(x0 + x1) / 2:.4f} {(y0 + y1) / 2:.4f} -0.01" '
            f'size="{(x1 - x0) / 2:.4f} {(y1 - y0) / 2:.4f} 0.01" material="{material_name(r.floor_material)}"/>'
        )
    for w in scene.walls:
        for b in wall_boxes(w):
            (cx, cy, cz), (hx, hy, hz) = b.centre, b.half
            parts.append(
                f'<geom name="{b.name}" type="box" pos="{cx:.4f} {cy:.4f} {cz:.4f}" euler="0 0 {b.yaw:.6f}" '
                f'size="{hx:.4f} {hy:.4f} {hz:.4f}" material="{material_name(b.material)}"/>'
            )
    for f in scene.furniture:
        x, y, z = f.position
        geoms = FURNITURE[f.category].geoms(f.size, f.material, f.shelf_heights)
        parts.append(f'<body name="{f.id}" pos="{x} {y} {z}" euler="0 0 {f.yaw}">{geoms}</body>')
    return "".join(parts)

