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


def _cmd_demo(args: argparse.Namespace) -> int:
    from harness.demo.run import run_demo
    from harness.demo.scoring import DemoConfig

    cfg = DemoConfig(frames=args.frames, height=args.height, width=args.width, encoder=args.encoder,
                     proposer=args.proposer)
    out = Path(args.out)
    print(f"Fusing {cfg.frames} rendered RGB-D frames ({cfg.width}x{cfg.height}) into a ConceptFusion map "
          f"with the {cfg.encoder!r} encoder ...")
    try:
        summary = run_demo(cfg, out)
    except ValueError as exc:
        print(f"cfharness demo: {exc}", file=sys.stderr)
        return 2
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
    print(f"map and PLY files written to {out}/")
    return 1 if wrong else 0


def _cmd_view(args: argparse.Namespace) -> int:
    from conceptfusion.errors import ConceptFusionError
    from harness.runner.jobs import import_plugins
    from harness.viewer.server import ViewerServer

    try:
        import_plugins(args.plugin)
        server = ViewerServer(args.map, encoder=args.encoder, host=args.host, port=args.port,
                              max_points=args.max_points)
    except (ConceptFusionError, ValueError, OSError) as exc:
        print(f"cfharness view: {exc}", file=sys.stderr)
        return 2
    print(f"Serving {args.map} at {server.url} (encoder {server.encoder_name}); Ctrl-C stops.", flush=True)
    if args.open:
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
    from conceptfusion.perception.registry import DEFAULT_ENCODER

    parser = _Parser(
        prog="cfharness",
        description="ConceptFusion mapping and agent evaluation harness.",
    )
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress (INFO level)")
    sub = parser.add_subparsers(dest="command")
    demo = sub.add_parser(
        "demo",
        help="build a map from rendered frames and query it (runs with no flags)",
        description="Fuse rendered RGB-D frames of a tabletop scene into a ConceptFusion map, "
        "query it by object names (one object is absent and must not be found), score the answers "
        "against ground truth, and write the map "
        "(.npz) and PLY point clouds (RGB and one heatmap per query).",
    )
    demo.add_argument("--out", default="runs/demo", help="output folder (default: runs/demo)")
    demo.add_argument("--frames", type=int, default=24, help="views on the orbit (default: 24)")
    demo.add_argument("--height", type=int, default=240, help="image height (default: 240)")
    demo.add_argument("--width", type=int, default=320, help="image width (default: 320)")
    demo.add_argument("--encoder", default=DEFAULT_ENCODER,
                      help=f"encoder spec (default: {DEFAULT_ENCODER}, the shipped image tower on a simulated "
                      "tabletop; 'color' runs the colour-only test encoder on a box scene)")
    demo.add_argument("--proposer", default="rgbd", choices=("rgbd", "gt"),
                      help="mask proposer on the tabletop (default: rgbd; gt reads the simulator's segmentation)")
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
                      f"maps and the demo's do; {DEFAULT_ENCODER} for a map that records none)")
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
