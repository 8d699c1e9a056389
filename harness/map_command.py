"""``cfharness map FRAMES_DIR``: fuse a folder of your own posed RGB-D frames into a map file.

The folder is read by :func:`conceptfusion.frame_folders.open_frame_folder` (the ``npz`` or the
TUM RGB-D layout, see docs/mapping.md), which checks every frame before the first is fused; the
mapper is :func:`conceptfusion.make_mapper`'s (the encoder's calibrated score floor on); the map
is written once, at the end, atomically, with what ``cfharness view`` needs to ask it the same
way (encoder, floor, lookup). A bad folder, flag or encoder exits with status 2 and one line on
stderr naming the file or flag; nothing is written then.
"""

from __future__ import annotations

import argparse
import math
import shlex
import sys
import textwrap
import time
from pathlib import Path

__all__ = ["add_map_command", "cmd_map"]


def add_map_command(sub) -> None:
    """Add the ``map`` subcommand to the ``cfharness`` subparsers ``sub``."""
    from conceptfusion.perception.featurizer import FLOOR_SETTINGS
    from conceptfusion.perception.registry import DEFAULT_ENCODER

    p = sub.add_parser(
        "map", help="fuse a folder of your own posed RGB-D frames into a map file (then: cfharness view)",
        description=textwrap.fill(
            "Fuse a folder of posed RGB-D frames into a ConceptFusion map file that cfharness view opens. Layouts: "
            "frame_000000.npz, frame_000001.npz ... (rgb, depth, K, cam_to_world; OpenCV camera, camera-to-world), or a "
            "TUM RGB-D folder (rgb.txt, depth.txt, groundtruth.txt, rgb/ and depth/ PNGs, intrinsics from camera.json or "
            "--intrinsics). Every frame is checked before the first is fused; nothing is written if one is refused. "
            "See docs/mapping.md.", 100),
        epilog="examples:\n  cfharness map my_frames --out runs/maps/mine.map.npz --encoder color\n"
        "  cfharness map rgbd_dataset_freiburg1_desk --intrinsics 517.3,516.5,318.6,255.3 --every 5 --setting household",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("frames", metavar="FRAMES_DIR", help="folder of frames (npz per frame, or TUM RGB-D)")
    p.add_argument("--out", default=None, help="map file to write (.npz; default: runs/maps/<folder name>.map.npz)")
    p.add_argument("--encoder", default=DEFAULT_ENCODER, help=f"encoder spec (default: {DEFAULT_ENCODER}; 'color' is the "
                   "quick colour-words test encoder; a registered one with --import)")
    p.add_argument("--setting", default="tabletop", choices=FLOOR_SETTINGS,
                   help="which calibrated score floor applies: objects close by (tabletop, default), a room seen from "
                   "a robot base (household), the object-search agents' view (search)")
    p.add_argument("--every", type=int, default=1, metavar="N", help="fuse every N-th frame (default: 1, all)")
    p.add_argument("--max-depth", type=float, default=6.0, metavar="M", help="ignore depth beyond M metres (default: 6)")
    p.add_argument("--intrinsics", default=None, metavar="FX,FY,CX,CY",
                   help="pinhole intrinsics in pixels for a TUM folder without camera.json (e.g. 517.3,516.5,318.6,255.3)")
    p.add_argument("--import", dest="plugin", action="append", metavar="MODULE",
                   help="import MODULE first (repeatable): a module that registers the encoder with conceptfusion.register_encoder")
    p.set_defaults(func=cmd_map)


def _intrinsics(text: str | None) -> tuple[float, ...] | None:
    if text is None:
        return None
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != 4 or not all(math.isfinite(v) for v in values):
        raise ValueError(f"--intrinsics: expected four numbers fx,fy,cx,cy (pixels), got {text!r}")
    return values


def _out_path(args: argparse.Namespace) -> Path:
    out = Path(args.out) if args.out else Path("runs") / "maps" / f"{Path(args.frames).resolve().name}.map.npz"
    if out.suffix != ".npz":
        raise ValueError(f"--out: expected a map file path ending in .npz, got {str(out)!r}")
    if out.is_dir():
        raise ValueError(f"--out: {out} is a folder; expected a map file path ending in .npz")
    blocking = next((a for a in out.parents if a.exists() and not a.is_dir()), None)
    if blocking is not None:
        raise ValueError(f"--out: {blocking} is a file, so {out} cannot be written under it")
    return out


def cmd_map(args: argparse.Namespace) -> int:
    """Run ``cfharness map``; returns the exit status (0 written, 2 refused: nothing written)."""
    from conceptfusion.errors import ConceptFusionError
    from conceptfusion.frame_folders import open_frame_folder
    from conceptfusion.mapper import make_mapper
    from conceptfusion.perception.featurizer import PerceptionSpec
    from harness.runner.jobs import import_plugins

    try:
        if args.every < 1:
            raise ValueError(f"--every: expected an integer >= 1, got {args.every}")
        if not (math.isfinite(args.max_depth) and args.max_depth > 0):
            raise ValueError(f"--max-depth: expected a positive number of metres, got {args.max_depth}")
        out = _out_path(args)
        import_plugins(args.plugin)
        PerceptionSpec.parse(args.encoder)  # a mistyped name fails here, naming the nearest, before any frame is read
        folder = open_frame_folder(args.frames, intrinsics=_intrinsics(args.intrinsics), every=args.every)
        skipped = f", {folder.skipped} rgb images without depth or pose close in time left out" if folder.skipped else ""
        print(f"Fusing {len(folder)} frames ({folder.layout} layout{skipped}) from {folder.path} with the "
              f"{args.encoder!r} encoder ...", flush=True)
        mapper = make_mapper(args.encoder, setting=args.setting, max_depth=args.max_depth)
        t0 = time.perf_counter()
        for frame in folder.frames():
            mapper.integrate(frame)
        seconds = time.perf_counter() - t0
        mapper.save(out)
    except (ConceptFusionError, ValueError, OSError) as exc:
        print(f"cfharness map: {exc}", file=sys.stderr)
        return 2
    floor = mapper.config.min_score
    print(f"fused {len(folder)} frames into {len(mapper.map)} points in {seconds:.1f} s "
          f"({len(folder) / max(seconds, 1e-9):.1f} frames/s); score floor "
          f"{'none' if floor is None else f'{floor:.3f}'} ({args.setting})")
    print(f"map written to {out}")
    print(f"open it: cfharness view {shlex.quote(str(out))}")
    return 0
