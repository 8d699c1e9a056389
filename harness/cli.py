"""The ``cfharness`` command line."""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

__all__ = ["main"]


class _Parser(argparse.ArgumentParser):
    """An ``ArgumentParser`` whose errors are one line on stderr (exit status 2) and that knows
    its flags, for "did you mean" on a mistyped one."""

    def __init__(self, *args, **kwargs) -> None:
        self.flags: list[str] = []
        super().__init__(*args, **kwargs)

    def add_argument(self, *args, **kwargs):
        action = super().add_argument(*args, **kwargs)
        self.flags.extend(action.option_strings)
        return action

    def error(self, message: str):
        self.exit(2, f"{self.prog}: {message} (see {self.prog} --help)\n")


def _unknown_flags(parser: _Parser, extra: list[str]) -> str:
    from conceptfusion.names import did_you_mean

    flag = next((e.partition("=")[0] for e in extra if e.startswith("-")), None)
    hint = did_you_mean(flag, parser.flags, n=2, cutoff=0.6) if flag else ""
    return f"unrecognized arguments: {' '.join(extra)}{hint}"


DEMO_WORLDS = {"v2": "embedded-v2", "v1": "embedded", "boxes": "color"}
"""The demo's worlds and the tower each is mapped with by default."""
DEMO_SCENE = "tabletop-v2-300005"
"""The v2 demo's tabletop (the first scene of the ``query-open`` suite)."""


def _demo_world(args: argparse.Namespace) -> tuple[str, str]:
    """(world, encoder) of a ``cfharness demo`` call: ``--encoder color`` alone means the box scene."""
    world = args.world or ("boxes" if args.encoder == "color" else "v2")
    return world, args.encoder or DEMO_WORLDS[world]


def _cmd_demo(args: argparse.Namespace) -> int:
    world, encoder = _demo_world(args)
    out = Path(args.out)
    print(f"Fusing {args.frames} rendered RGB-D frames ({args.width}x{args.height}) of a {world} tabletop into a "
          f"ConceptFusion map with the {encoder!r} encoder ...", flush=True)
    try:
        if world == "v2":
            code = _open_demo(args, encoder, out)
        else:
            code = _boxes_or_v1_demo(args, encoder, out)
    except ValueError as exc:
        print(f"cfharness demo: {exc}", file=sys.stderr)
        return 2
    print(f"map written to {out / 'map.npz'}; open it with:  cfharness view {out / 'map.npz'}")
    if args.view:
        return _serve(out / "map.npz", None, "127.0.0.1", 0, 2_000_000, open_browser=False) or code
    return code


def _open_demo(args: argparse.Namespace, encoder: str, out: Path) -> int:
    from harness.demo.open_world import run_open_demo

    s = run_open_demo(args.scene or DEMO_SCENE, encoder, frames=args.frames, width=args.width, height=args.height,
                      out_dir=out)
    print(f"scene: {s['scene']} ({', '.join(s['objects'])})")
    print(f"map: {s['num_points']} points, {s['bytes_per_point']:.0f} bytes/point; features and fusion "
          f"{s['map_s_per_frame'] * 1000:.0f} ms/frame")
    rows = [(o.kind, o.query, o.answer, o.truth + (f" ({o.group})" if o.group else ""), "yes" if o.correct else "NO")
            for o in s["outcomes"]]
    head = ("kind", "query", "map's answer", "truth", "right")
    caps = (8, 42, 30, 30, 5)  # about 120 columns; a longer cell ends in "~"
    widths = [min(max(len(r[i]) for r in rows + [head]), cap) for i, cap in enumerate(caps)]
    for r in [head] + rows:
        print("  ".join((c if len(c) <= w else c[:w - 1] + "~").ljust(w) for c, w in zip(r, widths)).rstrip())
    right = sum(o.correct for o in s["outcomes"])
    print(f"{right} of {len(rows)} right. Groups other than 'seen' are objects the tower never trained on "
          "(docs/model_card.md); rates over many scenes: cfharness run --suite query-open")
    return 0


def _boxes_or_v1_demo(args: argparse.Namespace, encoder: str, out: Path) -> int:
    from harness.demo.run import run_demo
    from harness.demo.scoring import DemoConfig

    cfg = DemoConfig(frames=args.frames, height=args.height, width=args.width, encoder=encoder, proposer=args.proposer)
    summary = run_demo(cfg, out)
    print(f"scene: {summary['scene']}")
    print(
        f"map: {summary['num_points']} points, {summary['bytes_per_point']:.0f} bytes/point; "
        f"features {summary['features_s_per_frame'] * 1000:.0f} ms/frame, "
        f"fusion {summary['fusion_s_per_frame'] * 1000:.0f} ms/frame"
    )
    print(f"{'query':<14} {'found':<6} {'ground truth':<14} {'median err (m)':>14} {'3D IoU':>7} {'relevancy':>9}")
    wrong = 0
    for o in summary["outcomes"]:
        ok = o.correct()
        wrong += not ok
        print(
            f"{o.query:<14} {str(o.found):<6} {str(o.truth):<14} {o.median_error_m:>14.3f} {o.iou_3d:>7.2f} {o.relevancy:>9.2f}"
            + ("" if ok else "   <- wrong")
        )
    print(f"PLY files written to {out}/")
    return 1 if wrong else 0


def _cmd_view(args: argparse.Namespace) -> int:
    from harness.runner.jobs import import_plugins

    try:
        import_plugins(args.plugin)
    except ValueError as exc:
        print(f"cfharness view: {exc}", file=sys.stderr)
        return 2
    return _serve(args.map, args.encoder, args.host, args.port, args.max_points, open_browser=args.open)


def _serve(map_path, encoder, host: str, port: int, max_points: int, *, open_browser: bool) -> int:
    """Serve a map in the viewer until Ctrl-C; 2 with one line on stderr when it cannot open."""
    from conceptfusion.errors import ConceptFusionError
    from harness.viewer.server import ViewerServer

    try:
        server = ViewerServer(map_path, encoder=encoder, host=host, port=port, max_points=max_points)
    except (ConceptFusionError, ValueError, OSError) as exc:
        print(f"cfharness view: {exc}", file=sys.stderr)
        return 2
    print(f"Serving {map_path} at {server.url} (encoder {server.encoder_name}); Ctrl-C stops.", flush=True)
    if open_browser:
        import webbrowser

        webbrowser.open(server.url)
    try:
        server.serve_forever()
    except KeyboardInterrupt:
        pass
    finally:
        server.httpd.server_close()
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="cfharness",
        description="ConceptFusion mapping and agent evaluation harness.",
    )
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress (INFO level)")
    sub = parser.add_subparsers(dest="command")
    demo = sub.add_parser(
        "demo",
        help="map a simulated tabletop and ask it open-vocabulary questions (runs with no flags)",
        description="Render a v2 tabletop (objects from the 91-category library) along an orbit, fuse the RGB-D frames "
        "into a ConceptFusion map with the shipped v2 tower, and ask it what the query-open and spatial-v2 suites "
        "ask: every object by name (marked seen or held out from the tower's training), a synonym, a material, a "
        "function, an absent object, and a spatial question; each answer is scored against the simulator. The map "
        "is written with its encoder, so that cfharness view opens it right. --world v1 maps a v1 tabletop (7 "
        "primitive kinds in 10 colours) with the v1 tower; --world boxes (or --encoder color) a box scene with the "
        "colour-only test encoder.",
        epilog="examples:\n  cfharness demo\n  cfharness demo --view              # then open the address it prints\n"
        "  cfharness demo --scene tabletop-v2-300028\n  cfharness demo --world v1\n  cfharness demo --encoder color",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    demo.add_argument("--out", default="runs/demo", help="output folder (default: runs/demo)")
    demo.add_argument("--world", choices=tuple(DEMO_WORLDS), help="v2 (default), v1 or boxes")
    demo.add_argument("--scene", help=f"v2 tabletop id (default: {DEMO_SCENE}; any file of scenes/tabletop-v2/)")
    demo.add_argument("--frames", type=int, default=24, help="views on the orbit (default: 24)")
    demo.add_argument("--height", type=int, default=240, help="image height (default: 240)")
    demo.add_argument("--width", type=int, default=320, help="image width (default: 320)")
    demo.add_argument("--encoder", default=None,
                      help="encoder spec (default: the world's tower: " + ", ".join(f"{w} {e}" for w, e in DEMO_WORLDS.items())
                      + "; 'color' alone selects the box scene)")
    demo.add_argument("--proposer", default="rgbd", choices=("rgbd", "gt"),
                      help="mask proposer of the v1 tabletop (default: rgbd; gt reads the simulator's segmentation)")
    demo.add_argument("--view", action="store_true", help="then serve the map in the viewer (until Ctrl-C)")
    demo.set_defaults(func=_cmd_demo)
    view = sub.add_parser(
        "view", help="open a map file in the browser: point cloud, text, click and image queries",
        description="Serve a map file (.npz, e.g. runs/demo/map.npz or RUN/replays/*.map.npz) on this machine's "
        "loopback address and draw it in the browser (WebGL): RGB or query heatmap, a text box, click on a point for "
        "the paper's click query, image upload, the found regions' boxes and medians, or 'not found' with the reason.",
        epilog="examples:\n  cfharness view runs/demo/map.npz\n  cfharness view runs/demo/map.npz --port 8765 --open\n"
        "  cfharness demo --encoder color && cfharness view runs/demo/map.npz --encoder color",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    view.add_argument("map", help="map file written by save_map (.npz)")
    view.add_argument("--encoder", default=None,
                      help="the encoder that answers the queries (default: the one the map file records, as the replays' "
                      f"maps and the demo's do; embedded for a map that records none)")
    view.add_argument("--import", dest="plugin", action="append", metavar="MODULE",
                      help="import MODULE first (repeatable): a module that registers the encoder with conceptfusion.register_encoder")
    view.add_argument("--port", type=int, default=0, help="TCP port (default: 0, a free one)")
    view.add_argument("--host", default="127.0.0.1", help="loopback address to bind: 127.0.0.1 (default), localhost or ::1")
    view.add_argument("--max-points", type=int, default=2_000_000,
                      help="points sent to the browser at most; larger maps are thinned (default: 2000000)")
    view.add_argument("--open", action="store_true", help="open the page in the default web browser")
    view.set_defaults(func=_cmd_view)
    from harness.map_command import add_map_command

    add_map_command(sub)
    from harness.commands import add_eval_commands

    add_eval_commands(sub)
    from harness.develop_command import add_develop_command

    add_develop_command(sub)
    parser.set_defaults(_commands=sub.choices)
    return parser


def _parse(parser: _Parser, argv: list[str] | None) -> argparse.Namespace:
    args, extra = parser.parse_known_args(argv)
    if extra:
        sub = args._commands.get(args.command) if args.command else None
        (sub or parser).error(_unknown_flags(sub or parser, extra))
    return args


def main(argv: list[str] | None = None) -> int:
    """Run the ``cfharness`` command line; returns the exit status (2: a bad argument or setting,
    reported in one line on stderr)."""
    parser = build_parser()
    args = _parse(parser, argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    if args.command is None:
        args = _parse(parser, ["demo"] + (argv if argv is not None else sys.argv[1:]))
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
