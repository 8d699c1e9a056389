"""The ``cfharness`` subcommands that evaluate: ``run``, ``compare``, ``report``, ``list``.

(The parser lives in :mod:`harness.cli`; these functions take its parsed arguments.)
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

__all__ = ["add_eval_commands"]


def _parse_kv(items: list[str] | None) -> dict:
    out = {}
    for item in items or []:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise ValueError(f"--agent-option: expected KEY=VALUE, got {item!r}")
        if key.strip() in out and out[key.strip()] != value.strip():
            raise ValueError(f"--agent-option {key.strip()}: given twice, {out[key.strip()]!r} and {value.strip()!r}")
        out[key.strip()] = value.strip()
    return out


def _print_summary(records: list[dict], stream=sys.stdout) -> None:
    from harness.report.stats import summarize

    rows = summarize(records)
    if not rows:
        print("no results", file=stream)
        return
    header = f"{'suite':<22} {'agent':<28} {'encoder':<10} {'n':>4} {'fail':>4} {'s/ep':>6}  metrics (mean [95% CI])"
    print(header, file=stream)
    print("-" * len(header), file=stream)
    for r in rows:
        parts = []
        for name, m in list(r.metrics.items())[:5]:
            if m.mean is None or m.mean != m.mean:
                continue
            ci = f" [{m.low:.2f}, {m.high:.2f}]" if m.low is not None and m.low == m.low else ""
            parts.append(f"{name} {m.mean:.3f}{ci}")
        wall = f"{r.wall_s:6.1f}" if r.wall_s == r.wall_s else f"{'-':>6}"
        print(f"{r.suite:<22} {r.agent:<28} {r.encoder:<10} {r.n:>4} {r.n_failed + r.n_timeout:>4} {wall}  " + "; ".join(parts), file=stream)


def cmd_run(args: argparse.Namespace) -> int:
    """``cfharness run``: every setting is checked (:class:`~harness.runner.run.RunConfig`) and
    the backend reached (:func:`~harness.runner.run.plan_run`) before anything is written to
    ``--out``; a bad one is one line on stderr and exit status 2."""
    from harness.runner.backends import RayUnavailableError
    from harness.runner.run import RunConfig, plan_run
    from harness.runner.suites import DEFAULT_SUITES

    suites = tuple(args.suite or DEFAULT_SUITES)
    try:
        config = RunConfig(
            suites=suites, agents=tuple(args.agent) if args.agent else None, encoder=args.encoder,
            agent_kwargs=_parse_kv(args.agent_option), limit=args.limit, seed=args.seed, backend=args.backend,
            workers=args.workers, address=args.address, timeout_s=args.timeout, plugins=tuple(args.plugin or ()),
        )
        plan = plan_run(config, args.out, resume=args.resume)
    except (ValueError, TypeError, FileExistsError, FileNotFoundError, RayUnavailableError) as exc:
        print(f"cfharness run: {exc}", file=sys.stderr)
        return 2
    t0 = time.monotonic()
    print(f"run {args.out}: suites {', '.join(suites)}; encoder {config.encoder}; backend {config.backend}", file=sys.stderr)
    try:
        records = plan.execute()
    except (ValueError, FileExistsError, FileNotFoundError, RayUnavailableError) as exc:
        print(f"cfharness run: {exc}", file=sys.stderr)
        return 2
    _print_summary(records)
    print(f"\n{len(records)} records in {Path(args.out) / 'results.jsonl'} ({time.monotonic() - t0:.0f} s)")
    if not args.no_report:
        from harness.report.markdown import write_report

        path = write_report([args.out], Path(args.out) / "report")
        print(f"report: {path}")
    return _check_floors(records, suites)


def _check_floors(records: list[dict], suites: tuple[str, ...]) -> int:
    """Non-zero when a regression suite's agent falls below its success floor."""
    from harness.runner.suites import get_suite

    bad = []
    for name in suites:
        suite = get_suite(name)
        for agent, floor in suite.floors.items():
            rs = [r for r in records if r["suite"] == name and r["agent"] == agent]
            if not rs:
                continue
            rate = sum(bool(r["metrics"].get("success")) for r in rs) / len(rs)
            if rate < floor:
                bad.append(f"{name}: {agent} succeeded on {rate:.0%} of {len(rs)} episodes, below its floor {floor:.0%}")
    for line in bad:
        print(f"REGRESSION {line}", file=sys.stderr)
    return 1 if bad else 0


def cmd_compare(args: argparse.Namespace) -> int:
    from harness.runner.results import load_runs
    from harness.report.stats import paired_comparison

    try:  # a missing folder, an empty or corrupt results file: one line and exit 2, no traceback
        records = load_runs(args.runs)
        res = paired_comparison(records, args.a, args.b, metric=args.metric, suite=args.suite)
    except (ValueError, OSError) as exc:
        print(f"cfharness compare: {exc}", file=sys.stderr)
        return 2
    print(json.dumps(res.as_dict() if hasattr(res, "as_dict") else res.__dict__, indent=2, default=str))
    return 0


def cmd_report(args: argparse.Namespace) -> int:
    from harness.report.markdown import write_report

    try:  # a missing folder, an empty or corrupt results file: one line and exit 2, no traceback
        path = write_report(list(args.runs), Path(args.out) if args.out else Path(args.runs[0]) / "report")
    except (ValueError, OSError) as exc:
        print(f"cfharness report: {exc}", file=sys.stderr)
        return 2
    print(f"report: {path}")
    return 0


def cmd_list(args: argparse.Namespace) -> int:
    from agents.registry import AGENTS
    from conceptfusion.perception.registry import describe_encoders
    from harness.runner.suites import SUITES

    print("suites:")
    for s in SUITES.values():
        print(f"  {s.name:<22} {s.description}")
    print("agents:")
    for a in AGENTS.values():
        opts = ", ".join(f"{k}={o.default!r}" + (f" ({o.expected})" if o.expected else "") for k, o in a.kwargs.items())
        tag = " (privileged)" if a.privileged else (" (map)" if a.uses_map else "")
        print(f"  {a.name:<16} {a.task:<20}{tag} {a.description}" + (f"\n  {'':<16} options: {opts}" if opts else ""))
    print("encoders:")
    for name, text in describe_encoders().items():
        print(f"  {name:<16} {text}")
    print("  oracle           privileged: ground-truth segmentation with MiniLM name embeddings (agents only)")
    return 0


def add_eval_commands(sub) -> None:
    """Add ``run``, ``compare``, ``report`` and ``list`` to the ``cfharness`` subparsers."""
    from harness.runner.backends import BACKENDS
    from harness.runner.suites import DEFAULT_SUITES, SUITES

    run = sub.add_parser(
        "run", help="run evaluation suites for agents and write results + a report",
        description="Roll agents through the shipped episodes and score maps against simulator ground truth. "
        f"With no --suite it runs {', '.join(DEFAULT_SUITES)} with every suite's default agents "
        "(map-equipped and map-free) on the embedded perception stack. Results go to OUT/results.jsonl "
        "(one line per episode, appended as episodes finish); an interrupted run continues with --resume.",
        epilog="examples:\n  cfharness run --suite search --agent map-navigator --agent frame-searcher --encoder oracle\n"
        "  cfharness run --suite rearrange --limit 10 --backend serial\n"
        "  cfharness run --suite search --agent mypkg.agents:MyAgent\n"
        "  cfharness run --import mypkg.register --suite rearrange --agent my-pusher\n"
        "  cfharness run --backend ray --address auto\n  cfharness run --out runs/main --resume",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    run.add_argument("--suite", action="append", help=f"suite to run, repeatable (choices: {', '.join(SUITES)})")
    run.add_argument("--agent", action="append", help="agent name or 'module:Class', repeatable (default: the suite's agents)")
    run.add_argument("--agent-option", action="append", metavar="KEY=VALUE", help="option for agents that accept it, repeatable")
    run.add_argument("--import", dest="plugin", action="append", metavar="MODULE",
                     help="import MODULE first (repeatable): a module that registers agents by name with agents.registry.register_agent")
    run.add_argument("--encoder", default="embedded", help="perception for map agents and map suites: embedded (default), oracle (privileged), hf:..., onnx:DIR")
    # numbers arrive as text: RunConfig checks them, with the same messages for Python callers
    run.add_argument("--limit", metavar="N", help="first N >= 1 episodes / scenes per suite")
    run.add_argument("--seed", metavar="N", default=0, help="episode seed >= 0 (default 0)")
    run.add_argument("--backend", default="process", metavar="{" + ",".join(BACKENDS) + "}",
                     help="where episodes run (default: process pool; serial runs in this process, where an agent "
                     "calling os._exit or crashing in native code ends the run)")
    run.add_argument("--workers", metavar="N", help="worker processes / Ray CPUs >= 1 (default: CPU count)")
    run.add_argument("--address", help="Ray cluster address for --backend ray: auto, HOST:PORT or ray://HOST:PORT "
                     "(default: start a local instance)")
    run.add_argument("--timeout", metavar="SECONDS", help="seconds > 0 per episode before it is recorded as timeout "
                     "(default: the suite's, 600)")
    run.add_argument("--out", default="runs/main", help="run folder (default: runs/main)")
    run.add_argument("--resume", action="store_true", help="finish an interrupted run in --out")
    run.add_argument("--no-report", action="store_true", help="skip writing the report")
    run.set_defaults(func=cmd_run)

    cmp_ = sub.add_parser("compare", help="paired comparison of two agents on the same episodes")
    cmp_.add_argument("runs", nargs="+", help="run folders")
    cmp_.add_argument("--a", required=True, help="agent label A")
    cmp_.add_argument("--b", required=True, help="agent label B")
    cmp_.add_argument("--metric", default="success")
    cmp_.add_argument("--suite")
    cmp_.set_defaults(func=cmd_compare)

    rep = sub.add_parser("report", help="write the Markdown report (tables, CIs, plots) for run folders")
    rep.add_argument("runs", nargs="+", help="run folders")
    rep.add_argument("--out", help="report folder (default: RUN/report)")
    rep.set_defaults(func=cmd_report)

    lst = sub.add_parser("list", help="list suites, agents and encoders")
    lst.set_defaults(func=cmd_list)
