"""Regenerate the shipped household scene files ``scenes/household/household-XXXX.json``.

    python scenes/make_scenes.py            # seeds 0-9 into scenes/household/
    python scenes/make_scenes.py --seeds 0 1 --out /tmp/scenes
    python scenes/make_scenes.py --picture docs/images/household.png   # cut-away overview of seed 0
"""

from __future__ import annotations

import argparse
import dataclasses
import math
from pathlib import Path
from typing import Iterable

from sim_envs.scenes.format import save_scene
from sim_envs.scenes.gen_household import generate_household

__all__ = ["HOUSEHOLD_DIR", "SHIPPED_SEEDS", "household_path", "write_household_scenes", "render_overview"]

HOUSEHOLD_DIR = Path(__file__).resolve().parent / "household"
"""Folder of the shipped household scenes."""
SHIPPED_SEEDS = tuple(range(10))
"""Seeds of the shipped household scenes."""


def household_path(seed: int, folder: Path = HOUSEHOLD_DIR) -> Path:
    """Path of the household scene file for ``seed``."""
    return Path(folder) / f"household-{int(seed):04d}.json"


def write_household_scenes(seeds: Iterable[int] = SHIPPED_SEEDS, folder: Path = HOUSEHOLD_DIR) -> list[Path]:
    """Generate and write (atomically) one household scene per seed; returns the paths."""
    return [save_scene(generate_household(int(s)), household_path(s, folder)) for s in seeds]


def render_overview(scene, width: int = 640, height: int = 480, *, wall_height: float = 0.9, elevation_deg: float = 55.0):
    """A cut-away RGB view of a household scene from high above, looking down at an angle from
    the south: walls cut at ``wall_height`` so every room shows.

    Shape:
        returns (height, width, 3) uint8.
    """
    import numpy as np

    from sim_envs.mujoco.scan import render_views
    from sim_envs.mujoco.scene import build_mujoco

    if not scene.rooms:
        raise ValueError(f"scene {scene.id}: an overview needs rooms; this scene has none")
    cut = dataclasses.replace(scene, walls=tuple(dataclasses.replace(w, height=min(w.height, wall_height)) for w in scene.walls))
    sim = build_mujoco(cut)
    fovy = 40.0
    lo = np.min([r.floor[0] for r in scene.rooms], axis=0)
    hi = np.max([r.floor[1] for r in scene.rooms], axis=0)
    c, span = (lo + hi) / 2, hi - lo
    half_v = math.radians(fovy / 2)
    half_h = math.atan(math.tan(half_v) * width / height)
    dist = max(0.6 * span[0] / math.tan(half_h), 0.8 * span[1] / math.tan(half_v))
    el = math.radians(elevation_deg)
    pose = ((c[0], c[1] - dist * math.cos(el), dist * math.sin(el)), (c[0], c[1] + 0.3, 0.0))
    return render_views(sim, [pose], width, height, fovy_deg=fovy, segmentation=False)[0].rgb


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=list(SHIPPED_SEEDS))
    ap.add_argument("--out", type=Path, default=HOUSEHOLD_DIR)
    ap.add_argument("--picture", type=Path, default=None, help="write a 640x480 overview PNG of the first seed's scene instead")
    args = ap.parse_args(argv)
    if args.picture is not None:
        import io

        from PIL import Image

        from conceptfusion.io_utils import atomic_write_bytes

        buf = io.BytesIO()
        Image.fromarray(render_overview(generate_household(args.seeds[0]))).save(buf, format="PNG")
        print(atomic_write_bytes(args.picture, buf.getvalue()))
        return
    for p in write_household_scenes(args.seeds, args.out):
        print(p)


if __name__ == "__main__":
    main()
