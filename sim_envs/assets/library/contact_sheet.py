"""A contact sheet of library instances rendered in MuJoCo (the README's picture).

Usage::

    MUJOCO_GL=egl python -m sim_envs.assets.library.contact_sheet docs/images/library.png
    python -m sim_envs.assets.library.contact_sheet out.png --per-category 2 --tile 96

Each tile shows one instance alone on a light floor, framed by its bounding box, labelled with
its category. By default one instance per category (the ``k``-th, cycling), in catalogue order.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from sim_envs import headless  # noqa: F401  (selects the GL backend before mujoco loads)

import mujoco  # noqa: E402

from conceptfusion.io_utils import atomic_write_bytes  # noqa: E402
from sim_envs.assets.library.catalogue import Instance, catalogue  # noqa: E402
from sim_envs.assets.library.export import export_instance  # noqa: E402
from sim_envs.assets.library.mjcf import library_asset_xml, library_geoms  # noqa: E402

__all__ = ["render_tile", "contact_sheet", "pick_instances", "main"]


def render_tile(inst: Instance, tile: int = 96) -> np.ndarray:
    """One instance rendered alone, 3/4 view from above.

    Shape:
        returns (tile, tile, 3) uint8 RGB.
    """
    size = export_instance(inst).size
    xml = (
        '<mujoco><visual><global offwidth="512" offheight="512"/><quality offsamples="4"/>'
        '<headlight ambient="0.45 0.45 0.45" diffuse="0.5 0.5 0.5"/></visual>'
        f"<asset>{library_asset_xml([inst.id])}"
        '<texture name="f" type="2d" builtin="flat" rgb1="0.93 0.93 0.93" width="8" height="8"/><material name="f" texture="f"/></asset>'
        '<worldbody><light pos="1 -1 3" dir="-0.3 0.3 -1" diffuse="0.5 0.5 0.5" castshadow="false"/>'
        '<geom type="plane" size="20 20 0.1" material="f"/>'
        f'<body pos="0 0 0">{library_geoms(inst.id)}</body></worldbody></mujoco>'
    )
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    cam = mujoco.MjvCamera()
    cam.lookat[:] = (0.0, 0.0, size[2] * 0.45)
    cam.distance = 1.9 * max(size) + 0.02
    cam.azimuth, cam.elevation = -60.0, -28.0
    with mujoco.Renderer(model, tile * 2, tile * 2) as r:
        r.update_scene(data, cam)
        img = r.render()
    import cv2

    return cv2.resize(img, (tile, tile), interpolation=cv2.INTER_AREA)


def pick_instances(per_category: int = 1, limit: int | None = None) -> list[Instance]:
    """``per_category`` instances of every category (spread over its instances), in order."""
    cat = catalogue()
    out = []
    for name in cat.categories:
        items = cat.instances_of(name)
        step = max(1, len(items) // max(per_category, 1))
        out.extend(items[(j * step + 3) % len(items)] for j in range(min(per_category, len(items))))
    return out[:limit]


def contact_sheet(instances: list[Instance], tile: int = 96, columns: int = 13) -> np.ndarray:
    """A grid of :func:`render_tile` images with category labels.

    Shape:
        returns (rows * tile, columns * tile, 3) uint8 RGB.
    """
    import cv2

    rows = math.ceil(len(instances) / columns)
    sheet = np.full((rows * tile, columns * tile, 3), 255, np.uint8)
    for k, inst in enumerate(instances):
        img = render_tile(inst, tile).copy()
        label = inst.category if len(inst.category) <= 13 else inst.category[:12] + "."
        cv2.putText(img, label, (3, tile - 5), cv2.FONT_HERSHEY_SIMPLEX, 0.3, (20, 20, 20), 1, cv2.LINE_AA)
        r, c = divmod(k, columns)
        sheet[r * tile:(r + 1) * tile, c * tile:(c + 1) * tile] = img
    return sheet


def main(argv: list[str] | None = None) -> int:
    """Render the contact sheet to a PNG."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--per-category", type=int, default=1)
    ap.add_argument("--tile", type=int, default=72)
    ap.add_argument("--columns", type=int, default=13)
    args = ap.parse_args(argv)
    import cv2

    sheet = contact_sheet(pick_instances(args.per_category), args.tile, args.columns)
    ok, buf = cv2.imencode(".png", sheet[..., ::-1], [cv2.IMWRITE_PNG_COMPRESSION, 9])
    if not ok:
        raise SystemExit("could not encode the PNG")
    atomic_write_bytes(args.out, buf.tobytes())
    print(f"wrote {args.out} ({sheet.shape[1]}x{sheet.shape[0]}, {len(buf) // 1024} KB)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
