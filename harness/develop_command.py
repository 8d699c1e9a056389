"""``cfharness develop TOOL [ARGS...]``: the development tools behind one command.

Agent settings, score floors, the regression suites' calibration, the tower's training and the
sealed headline measurement each have a command-line tool, a module with ``main(argv)``
(:data:`TOOLS`). ``cfharness develop TOOL ARGS...`` runs that ``main`` with ``ARGS`` (so
``cfharness develop TOOL --help`` shows the tool's own flags); ``cfharness develop`` alone lists
the tools. ``python -m MODULE ARGS...`` runs the same tool.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from typing import NamedTuple

__all__ = ["TOOLS", "DevelopTool", "add_develop_command", "cmd_develop", "tool_listing"]


class DevelopTool(NamedTuple):
    """One development tool: the module whose ``main(argv)`` runs it, and what it is for."""

    module: str
    summary: str


TOOLS: dict[str, DevelopTool] = {
    "episodes": DevelopTool("harness.runner.develop",
                            "run agents on calibration or validation episodes, where agent settings are chosen (resumable)"),
    "query-open": DevelopTool("harness.maps.query_open_develop",
                              "query-open on calibration tables: what the score floor costs, per query kind"),
    "spatial": DevelopTool("harness.maps.spatial_develop", "spatial-question settings on calibration scenes"),
    "bounds": DevelopTool("harness.runner.bounds",
                          "calibrate the regression suites' success bounds (--calibrate) or check them (--check)"),
    "headline": DevelopTool("harness.report.headline", "measure the headline figures once on the sealed test set"),
    "sim-to-sim": DevelopTool("harness.report.sim_to_sim", "pair PyBullet runs of a suite's -pybullet variant with the "
                              "sealed MuJoCo records: the README's sim-to-sim table"),
    "instruct": DevelopTool("harness.report.instruct", "the planner-in-the-loop comparison on instruct-v2 runs: the "
                            "README's instruction table"),
    "train": DevelopTool("tower_training.train", "train, evaluate and export the embedded image tower (--world v2: the v2 tower)"),
    "fit": DevelopTool("tower_training.fit", "fit the v2 image tower on a training bundle, on any torch device"),
    "evaluate": DevelopTool("tower_training.evaluate", "retrieval metrics of the embedded image tower on labelled crops"),
    "in-scene": DevelopTool("tower_training.in_scene",
                            "in-scene retrieval on the validation tables: does a name pick its own object?"),
    "room-floor": DevelopTool("tower_training.room_floor", "derive the v2 tower's score floors for apartments"),
    "oracle-floor": DevelopTool("tower_training.oracle_floor", "derive the oracle perception's score floor"),
}
"""Tool name -> its module and a one-line summary, in the order of the listing."""


def tool_listing() -> str:
    """The tools, one line each: name, summary, module."""
    width = max(map(len, TOOLS))
    lines = ["development tools (cfharness develop TOOL --help for a tool's flags):"]
    lines += [f"  {name:<{width}}  {tool.summary} (python -m {tool.module})" for name, tool in TOOLS.items()]
    return "\n".join(lines)


def add_develop_command(sub) -> None:
    """Add the ``develop`` subcommand to the ``cfharness`` subparsers ``sub``."""
    p = sub.add_parser(
        "develop", help="development tools: agent settings, score floors, regression calibration, tower training",
        description="Run a development tool: cfharness develop TOOL ARGS... passes ARGS to the tool; with no TOOL, "
        "list the tools. Settings are chosen on calibration and validation episodes, never on the evaluation ones.",
        epilog="examples:\n  cfharness develop\n  cfharness develop episodes --suite search-v2 --agent map-navigator "
        "--out runs/develop/nav\n  cfharness develop bounds --check\n  cfharness develop room-floor --help",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("tool", nargs="?", metavar="TOOL", help="the tool to run: " + ", ".join(TOOLS))
    p.add_argument("args", nargs=argparse.REMAINDER, metavar="ARGS", help="the tool's arguments")
    p.set_defaults(func=cmd_develop)


def cmd_develop(args: argparse.Namespace) -> int:
    """List the tools (no tool named), or run one with its arguments; 2 for an unknown tool."""
    if args.tool is None:
        print(tool_listing())
        return 0
    tool = TOOLS.get(args.tool)
    if tool is None:
        from conceptfusion.names import unknown_name_error

        print(f"cfharness develop: {unknown_name_error('tool', args.tool, TOOLS)}", file=sys.stderr)
        return 2
    try:
        code = importlib.import_module(tool.module).main(list(args.args))
    except SystemExit as exc:  # argparse inside the tool: --help (0) or a bad flag (2)
        code = exc.code
    if isinstance(code, str):  # sys.exit("message")
        print(code, file=sys.stderr)
        return 1
    return int(code or 0)
