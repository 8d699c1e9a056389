"""The ``cfharness`` subcommands that evaluate: ``run``, ``compare``, ``report``, ``replay``, ``list``.

(The parser lives in :mod:`harness.cli`; these functions take its parsed arguments.)
"""

from __future__ import annotations

import argparse
import contextlib
import json
import shlex
import signal
import sys
import threading
import time
from pathlib import Path

__all__ = ["EXIT_NO_ROOM", "add_eval_commands", "fail_fast_stop", "parse_agent_options"]


def parse_agent_options(items: list[str] | None, flag: str = "--agent-option") -> dict:
    """``--agent-option KEY=VALUE`` items (or those of another ``flag``) as a dict of strings; a
    malformed item or a key given twice with different values is a ``ValueError`` naming it."""
    out = {}
    for item in items or []:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise ValueError(f"{flag}: expected KEY=VALUE, got {item!r}")
        if key.strip() in out and out[key.strip()] != value.strip():
            raise ValueError(f"{flag} {key.strip()}: given twice, {out[key.strip()]!r} and {value.strip()!r}")
        out[key.strip()] = value.strip()
    return out


def _print_summary(records: list[dict], stream=None) -> None:
    """The summary table of ``records`` on ``stream`` (default: ``sys.stdout`` as it is now)."""
    from harness.report.stats import summarize

    stream = sys.stdout if stream is None else stream
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


_SETTINGS_FLAGS = {"suite": "--suite", "agent": "--agent", "agent_option": "--agent-option", "encoder": "--encoder",
                   "limit": "--limit", "seed": "--seed", "seeds": "--seeds", "plugin": "--import", "episodes": "--episodes",
                   "scenes": "--scenes"}
"""``cfharness run`` arguments that are the run's settings (stored in ``run.json``); attribute -> flag."""


def _run_config(args: argparse.Namespace):
    """The :class:`~harness.runner.run.RunConfig` of ``cfharness run``'s arguments. ``--resume``
    with none of the settings flags (:data:`_SETTINGS_FLAGS`) continues with the settings stored
    in ``--out``'s ``run.json``, so ``cfharness run --out DIR --resume`` finishes any run."""
    from harness.runner.results import read_run_config
    from harness.runner.run import RunConfig
    from harness.runner.suites import DEFAULT_SUITES, episodes_suite_name

    common = dict(backend=args.backend, workers=args.workers, address=args.address, timeout_s=args.timeout,
                  memory_limit_mb=args.memory_limit_mb, record=args.record)
    if args.resume and all(getattr(args, name) is None for name in _SETTINGS_FLAGS):
        from harness.runner.folder import check_run_folder

        stored = read_run_config(check_run_folder(args.out)).get("settings")
        if not isinstance(stored, dict) or not isinstance(stored.get("suites"), list):
            raise ValueError(f"{args.out}: expected stored settings with a 'suites' list in run.json, got {stored!r}")
        return RunConfig(
            suites=tuple(stored["suites"]), agents=tuple(stored["agents"]) if stored.get("agents") else None,
            encoder=stored.get("encoder"), agent_kwargs=dict(stored.get("agent_kwargs") or {}), limit=stored.get("limit"),
            seed=stored.get("seed", 0), seeds=stored.get("seeds", 1), plugins=tuple(stored.get("plugins") or ()), **common,
        )
    if args.scenes is not None and not args.episodes:
        raise ValueError(f"--scenes: names the folder of --episodes files' scenes; got --scenes {args.scenes!r} without --episodes")
    own = tuple(episodes_suite_name(f, args.scenes) for f in args.episodes or ())
    return RunConfig(
        suites=tuple(args.suite or ()) + own if own else tuple(args.suite or DEFAULT_SUITES),
        agents=tuple(args.agent) if args.agent else None, encoder=args.encoder,
        agent_kwargs=parse_agent_options(args.agent_option), limit=args.limit,
        seed=0 if args.seed is None else args.seed, seeds=1 if args.seeds is None else args.seeds,
        plugins=tuple(args.plugin or ()), **common,
    )


class RunTerminated(KeyboardInterrupt):
    """``SIGTERM`` during ``cfharness run``: stops the run as Ctrl-C does (a ``KeyboardInterrupt``,
    so every job lets it through and closes its environments), with exit status 143."""


@contextlib.contextmanager
def _sigterm_stops_the_run():
    """Within the block, ``SIGTERM`` raises :class:`RunTerminated` in the main thread (as
    ``SIGINT`` raises ``KeyboardInterrupt``); the previous handler comes back afterwards."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def on_term(signum, frame):
        raise RunTerminated()

    previous = signal.signal(signal.SIGTERM, on_term)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


EXIT_NO_ROOM = 74
"""Exit status of a ``cfharness run`` stopped because its run folder's file system is full, over
quota or read-only (``EX_IOERR`` of ``sysexits.h``): not 1, which says an agent regressed, nor 2,
which says the command was refused before it started."""


def _kept(plan) -> str:
    """The finished records of ``plan``'s results file, in words ("3 finished records")."""
    from harness.runner.results import load_results

    try:
        n = len(load_results(plan.results))
    except (ValueError, OSError):
        return "the finished records"
    return f"{n} finished record{'' if n == 1 else 's'}"


def _resume_command(out: str) -> str:
    return f"cfharness run --out {shlex.quote(str(out))} --resume"


def _interrupted(exc: KeyboardInterrupt, out: str, plan) -> int:
    """One line on stderr for a run stopped by Ctrl-C (exit status 130) or ``SIGTERM`` (143):
    what is kept and the command that finishes the run."""
    signame, status = ("SIGTERM", 143) if isinstance(exc, RunTerminated) else ("Ctrl-C", 130)
    if plan is None:
        print(f"cfharness run: stopped by {signame} before the first episode; nothing was run", file=sys.stderr)
        return status
    print(f"cfharness run: stopped by {signame}; {_kept(plan)} kept in {plan.results} "
          f"({len(plan.jobs)} planned); finish the run with: {_resume_command(out)}", file=sys.stderr)
    return status


def _no_room(exc, out: str, plan) -> int:
    """One line on stderr for a run stopped by a full (over-quota, read-only) file system
    (a :class:`~harness.runner.folder.RunFolderFullError`), exit status :data:`EXIT_NO_ROOM`:
    what could not be written, what is kept and the command that finishes the run once there is
    room. When the run was never planned (``plan`` None: its lock file or ``run.json`` could not
    be written) nothing was run, and the same command runs it."""
    lead = f"cfharness run: --out {out}: could not write {exc.what} ({exc.filename}): {exc.strerror}"
    if plan is None:
        print(f"{lead}; nothing was run; free space and run the command again", file=sys.stderr)
    else:
        print(f"{lead}; {_kept(plan)} kept in {plan.results} ({len(plan.jobs)} planned); free space and finish the run "
              f"with: {_resume_command(out)}", file=sys.stderr)
    return EXIT_NO_ROOM


def cmd_run(args: argparse.Namespace) -> int:
    """``cfharness run``: every setting is checked (:class:`~harness.runner.run.RunConfig`) and
    the backend reached (:func:`~harness.runner.run.plan_run`) before anything is written to
    ``--out``; a bad one is one line on stderr and exit status 2. The run holds ``--out`` for its
    whole life (:mod:`harness.runner.folder`): a second run on the same folder is refused with
    status 2, naming the holder. Ctrl-C stops the run with status 130 (``SIGTERM``: 143), keeping
    every finished record and printing the command that resumes it. A file system that fills up
    (or goes over quota, or turns read-only) while the run writes its folder stops the run the
    same way with status :data:`EXIT_NO_ROOM` (74), naming what could not be written (the lock
    file, ``run.json``, a results record, the report); an ``--out`` that is read-only from the
    start is refused with status 2."""
    from harness.runner.folder import RunFolderFullError

    plan = None
    try:
        with _sigterm_stops_the_run():
            try:
                config = _run_config(args)
                bound_as = _parse_bound_as(args.bound_as, config)
                plan = _plan(config, args.out, args.resume)
            except RunFolderFullError:
                raise
            except (ValueError, TypeError, OSError) as exc:
                print(f"cfharness run: {exc}", file=sys.stderr)
                return 2
            try:
                return _execute(args, config, plan, bound_as)
            finally:
                plan.close()
    except KeyboardInterrupt as exc:
        return _interrupted(exc, args.out, plan)
    except RunFolderFullError as exc:
        return _no_room(exc, args.out, plan)


def _plan(config, out: str, resume: bool):
    """:func:`~harness.runner.run.plan_run`, with a Ray backend that cannot start reported as a bad setting."""
    from harness.runner.backends import RayUnavailableError
    from harness.runner.run import plan_run

    try:
        return plan_run(config, out, resume=resume)
    except RayUnavailableError as exc:
        raise ValueError(str(exc)) from exc


def _execute(args: argparse.Namespace, config, plan, bound_as: dict[str, str]) -> int:
    """Run a planned ``cfharness run``: the jobs, the summary, the report and the regression bounds."""
    from harness.runner.backends import RayUnavailableError

    suites = config.suites
    t0 = time.monotonic()
    print(f"run {args.out}: suites {', '.join(suites)}; encoder {config.encoder or 'each suite default'}; backend {config.backend}", file=sys.stderr)
    stopped: list[dict] = []  # the record that settled a regression (--fail-fast)
    stop = None
    if args.fail_fast:
        from harness.runner.results import load_results

        settled = fail_fast_stop(plan.jobs, suites, agents=config.agents, bound_as=bound_as,
                                 done=load_results(plan.results))

        def settle(rec: dict) -> bool:
            if settled(rec):
                stopped.append(rec)
                return True
            return False

        stop = settle
    try:
        records = plan.execute(stop=stop)
    except (ValueError, FileExistsError, FileNotFoundError, RayUnavailableError) as exc:
        print(f"cfharness run: {exc}", file=sys.stderr)
        return 2
    _print_summary(records)
    print(f"\n{len(records)} records in {Path(args.out) / 'results.jsonl'} ({time.monotonic() - t0:.0f} s)")
    if not args.no_report:
        from harness.replay.video import render_missing_videos
        from harness.report.html import write_reports
        from harness.runner.folder import writing

        render_missing_videos(args.out)  # a video that cannot be written is logged; the report goes on
        with writing("the report", Path(args.out) / "report"):
            path, html_path = write_reports([args.out], Path(args.out) / "report")
        print(f"report: {path}\nHTML report: {html_path}")
    if stopped:
        print(f"--fail-fast: stopped after {stopped[0]['suite']} {stopped[0]['agent']} {stopped[0]['episode_id']} settled a "
              f"regression; --resume runs the rest", file=sys.stderr)
    return _check_bounds(records, suites, agents=config.agents, bound_as=bound_as, limited=config.limit is not None,
                         stopped_early=bool(stopped))


def _parse_bound_as(items: list[str] | None, config) -> dict[str, str]:
    """``--bound-as AGENT=BUILTIN`` -> {agent: built-in agent}; ``ValueError`` for a bad item."""
    from agents.registry import AGENTS
    from conceptfusion.names import unknown_name_error

    out: dict[str, str] = {}
    for item in items or []:
        agent, sep, builtin = (x.strip() for x in item.partition("="))
        if not sep or not agent or not builtin:
            raise ValueError(f"--bound-as: expected AGENT=BUILTIN (e.g. mypkg.agents:MyPusher=map-pusher), got {item!r}")
        if agent not in (config.agents or ()):
            raise ValueError(f"--bound-as {item}: {agent!r} is not an --agent of this run "
                             f"(agents: {', '.join(config.agents or ()) or 'the suites defaults'})")
        if builtin not in AGENTS:
            raise unknown_name_error("built-in agent", builtin, AGENTS)
        out[agent] = builtin
    return out


def _held_bounds(suites: tuple[str, ...], agents: tuple[str, ...] | None, bound_as: dict[str, str]) -> tuple[list[tuple], list[str]]:
    """The bounds a run is held to, ``(suite, agent, kind, value, pinned, held)`` each (``held``:
    how the report names it), and the problems found before any record is read (a regression
    suite with no bounds, an agent borrowing a bound its reference lacks)."""
    from harness.runner.suites import get_suite

    held_bounds, bad = [], []
    for name in suites:
        suite = get_suite(name)
        bounds = {**{a: ("lower", v) for a, v in suite.lower_bounds.items()},
                  **{a: ("upper", v) for a, v in suite.upper_bounds.items()}}
        if suite.calibration_file is not None and not bounds:
            bad.append(f"{name}: no calibrated bounds (run cfharness develop bounds --calibrate)")
            continue
        to_check = list(bounds) if agents is None else [a for a in agents if a in bounds or a in bound_as]
        for agent in to_check:
            ref = bound_as.get(agent, agent)
            if ref not in bounds:
                bad.append(f"{name}: {agent} is held to the bound of {ref}, which has none in this suite "
                           f"(agents with bounds: {', '.join(bounds)})")
                continue
            kind, value = bounds[ref]
            held = f"its {kind} bound {value:.0%}" + (f" (that of {ref})" if ref != agent else "")
            held_bounds.append((name, agent, kind, value, suite.agent_limits.get(ref, suite.limit), held))
    return held_bounds, bad


def _broken(kind: str, value: float, k: int, n: int, planned: int | None = None) -> bool:
    """Whether ``k`` successes in ``n`` episodes break the bound for certain. With ``planned``
    (the episodes the run would have run, >= n), the ones not run count at their best: as
    successes against a lower bound, as failures against an upper bound."""
    total = max(n, planned or n)
    if kind == "lower":
        return k + (total - n) < value * total - 1e-9
    return k > value * total + 1e-9


def fail_fast_stop(jobs, suites: tuple[str, ...], *, agents: tuple[str, ...] | None = None,
                   bound_as: dict[str, str] | None = None, done: list[dict] | None = None):
    """A ``stop`` callback for :meth:`~harness.runner.run.RunPlan.execute` (``--fail-fast``): True
    once a record settles a regression: an episode of a bounded agent crashed, or its successes
    so far cannot reach its lower bound (or already pass its upper bound) whatever its remaining episodes
    of ``jobs`` (every job of the run) do. ``done``: the records a resumed run already holds,
    counted first."""
    from harness.runner.results import latest_records

    bounds, _ = _held_bounds(suites, agents, dict(bound_as or {}))
    watched = {(suite, agent): (kind, value) for suite, agent, kind, value, _, _ in bounds}
    planned: dict[tuple[str, str], int] = {}
    for job in jobs:
        key = (job.suite, job.agent)
        planned[key] = planned.get(key, 0) + 1
    seen: dict[tuple[str, str], list[int]] = {}

    def stop(rec: dict) -> bool:
        key = (rec.get("suite"), rec.get("agent"))
        if key not in watched:
            return False
        if rec.get("status") == "failed":
            return True
        counts = seen.setdefault(key, [0, 0])
        counts[0] += bool(rec.get("metrics", {}).get("success"))
        counts[1] += 1
        kind, value = watched[key]
        return _broken(kind, value, counts[0], counts[1], planned.get(key, counts[1]))

    for rec in latest_records(done or []):
        stop(rec)
    return stop


def _check_bounds(records: list[dict], suites: tuple[str, ...], *, agents: tuple[str, ...] | None = None,
                  bound_as: dict[str, str] | None = None, limited: bool = False, stopped_early: bool = False) -> int:
    """1 when an agent of a regression suite breaks its calibrated bound
    (:mod:`harness.runner.bounds`), with one ``REGRESSION`` line on stderr per problem; else 0.

    Checked per suite of ``suites`` that has bounds: every agent with a bound when
    ``agents`` (the run's ``--agent`` list) is None, else the named ones that have a bound or
    borrow one through ``bound_as`` (``{agent: built-in agent whose bound it is held to}``).
    A problem is: a success rate below the agent's lower bound or above its upper bound; an episode that
    crashed (status ``failed``: the agent or environment raised); an agent to check with no records; fewer episodes than its bound is sized for (unless the run was ``limited``
    with ``--limit``, which only prints a note); a regression suite with no calibrated bounds.
    Failed and timed-out episodes count as unsuccessful. A run ``stopped_early``
    (``--fail-fast``) is judged on the episodes it ran, each missing one counted at its best for
    the agent (a success against a lower bound, a failure against an upper bound), so only settled
    verdicts are reported.
    """
    from harness.report.stats import metric_value

    bounds, bad = _held_bounds(suites, agents, dict(bound_as or {}))
    notes = []
    for name, agent, kind, value, pinned, held in bounds:
        rs = {(r.get("episode_id"), r.get("seed")): r for r in records if r["suite"] == name and r["agent"] == agent}
        if not rs and not stopped_early:
            bad.append(f"{name}: {agent} has no records; {held} needs its {pinned or 'all'} pinned episodes run")
            continue
        episodes = len({e for e, _ in rs})
        if pinned is not None and episodes < pinned:
            line = f"{name}: {agent} ran {episodes} of the {pinned} pinned episodes {held} is sized for"
            quiet = limited or stopped_early
            (notes if quiet else bad).append(line + (" (--limit)" if limited else " (--fail-fast stopped the run)" if stopped_early else ""))
        k = sum(bool(metric_value(r, "success")) for r in rs.values())
        n = len(rs)
        crashed = sorted(e for (e, _), r in rs.items() if r.get("status") == "failed")
        if crashed:
            bad.append(f"{name}: {agent} crashed on {len(crashed)} of {n} episodes ({', '.join(map(str, crashed[:3]))}"
                       f"{', ...' if len(crashed) > 3 else ''}); see their records' error")
        planned = max(n, pinned or n) if stopped_early else n
        if not _broken(kind, value, k, n, planned):
            continue
        rate = f"succeeded on {k} of {n} episodes" + (f" ({k / n:.0%})" if n else "")
        if planned > n:
            rate += f" before --fail-fast stopped the run (at most {k + planned - n if kind == 'lower' else k} of {planned})"
        if kind == "lower":
            bad.append(f"{name}: {agent} {rate}, below {held}")
        else:
            bad.append(f"{name}: {agent} {rate}, above {held}: a random agent should not succeed that often (a broken success function?)")
    for line in notes:
        print(f"note: {line}", file=sys.stderr)
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
    """``cfharness report RUN...``: the Markdown and HTML reports in ``--out`` (default
    ``RUN/report``), or with ``--bundle [PATH]`` a portable bundle (default ``RUN/report-bundle``;
    a ``.zip`` path also writes the zip). A bad argument or input is one line and exit status 2."""
    from harness.replay.video import render_missing_videos
    from harness.report.html import write_reports

    if args.results_page:
        from harness.report.results_page import write_results_page

        try:
            page = write_results_page(list(args.runs), args.results_page)
        except (ValueError, OSError) as exc:
            print(f"cfharness report: {exc}", file=sys.stderr)
            return 2
        print(f"results page: {page}")
        return 0
    bundle = args.bundle
    if args.bundle_maps and bundle is None:
        bundle = ""  # --bundle-maps alone: the default bundle, maps included
    if bundle is not None and args.out:
        print("cfharness report: --out and --bundle both name where to write; give one (--bundle PATH)", file=sys.stderr)
        return 2
    try:  # a missing folder, an empty or corrupt results file: one line and exit 2, no traceback
        for run in args.runs:  # videos of the recordings that have none yet, beside them
            render_missing_videos(run)
        if bundle is not None:
            from harness.report.bundle import write_bundle

            done = write_bundle(list(args.runs), Path(bundle) if bundle else Path(args.runs[0]) / "report-bundle",
                                maps=args.bundle_maps)
        else:
            path, html_path = write_reports(list(args.runs), Path(args.out) if args.out else Path(args.runs[0]) / "report")
    except (ValueError, OSError) as exc:
        print(f"cfharness report: {exc}", file=sys.stderr)
        return 2
    if bundle is not None:
        print(f"report bundle: {done.folder} ({len(done.files)} files: {done.videos} videos, "
              f"{done.maps if args.bundle_maps else 'no'} maps){f'; zip: {done.zip_path}' if done.zip_path else ''}")
    else:
        print(f"report: {path}\nHTML report: {html_path}")
    return 0


def cmd_replay(args: argparse.Namespace) -> int:
    """``cfharness replay RUN EPISODE``: find the recording (:func:`~harness.replay.find.find_recording`)
    and render it (:func:`~harness.replay.video.render_video`); a bad argument or file is one line
    on stderr and exit status 2."""
    from harness.replay.find import find_recording
    from harness.replay.video import render_video

    try:
        path = find_recording(args.run, args.episode, suite=args.suite, agent=args.agent, seed=args.seed)
        video = render_video(path, args.out, fps=args.fps)
    except (ValueError, OSError, ImportError) as exc:
        print(f"cfharness replay: {exc}", file=sys.stderr)
        return 2
    print(f"replay: {video}")
    return 0


def cmd_list(args: argparse.Namespace) -> int:
    from agents.registry import AGENTS
    from conceptfusion.perception.registry import describe_encoders
    from harness.runner.jobs import import_plugins
    from harness.runner.suites import SUITES

    try:
        import_plugins(args.plugin)
    except ValueError as exc:
        print(f"cfharness list: {exc}", file=sys.stderr)
        return 2

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
    print("  oracle-open      privileged: ground-truth segmentation and ground-truth grounding of descriptions (agents only)")
    print("  oracle[-open]:min_pixels=N  the same, labelling only segments of at least N pixels of a frame")
    return 0


def add_eval_commands(sub) -> None:
    """Add ``run``, ``compare``, ``report``, ``replay`` and ``list`` to the ``cfharness`` subparsers."""
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
        "  cfharness run --episodes my/episodes.jsonl --scenes my/scenes --out runs/mine\n"
        "  cfharness run --import mypkg.register --suite rearrange --agent my-pusher\n"
        "  cfharness run --backend ray --address auto\n  cfharness run --out runs/main --resume\n\n"
        "exit status:\n  0    done\n  1    an agent broke its regression bound (REGRESSION lines)\n"
        "  2    refused before starting: a bad setting, a busy or read-only --out\n"
        "  74   the disk filled up (or went over quota, or turned read-only) during the run\n"
        "  130  Ctrl-C (143: SIGTERM)\n"
        "  after 74, 130 and 143 the finished records are kept, and --resume finishes the run",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    run.add_argument("--suite", action="append", help=f"suite to run, repeatable (choices: {', '.join(SUITES)})")
    run.add_argument("--episodes", action="append", metavar="FILE",
                     help="your own episode file (cf-episodes JSON lines, docs/environments.md), repeatable: validated like the "
                     "shipped ones, then run with the agents and settings of rearrange-v2 or search-v2 (by the file's task); "
                     "without --suite only these run")
    run.add_argument("--scenes", metavar="DIR", help="folder the --episodes files' scene references resolve under "
                     "(default: the shipped scenes/)")
    run.add_argument("--agent", action="append", help="agent name or 'module:Class', repeatable (default: the suite's agents)")
    run.add_argument("--agent-option", action="append", metavar="KEY=VALUE", help="option for agents that accept it, repeatable")
    run.add_argument("--import", dest="plugin", action="append", metavar="MODULE",
                     help="import MODULE first (repeatable): a module that registers agents (agents.register_agent) or encoders "
                     "(conceptfusion.register_encoder) by name")
    run.add_argument("--encoder", default=None, help="perception for map agents and map suites: embedded, embedded-v2, oracle, oracle-open (privileged), hf:..., onnx:DIR, or a name an --import module registered (default: each suite's own, the shipped tower of its world: embedded for v1 suites, embedded-v2 for v2 suites)")
    # numbers arrive as text: RunConfig checks them, with the same messages for Python callers
    run.add_argument("--limit", metavar="N", help="first N >= 1 episodes / scenes per suite")
    run.add_argument("--seed", metavar="N", help="episode seed >= 0 (default 0)")
    run.add_argument("--seeds", metavar="N", help="seeds per episode >= 1: each episode runs with seeds "
                     "SEED, SEED+1, ..., SEED+N-1, and the report gives the between-seed spread (default 1)")
    run.add_argument("--backend", default="process", metavar="{" + ",".join(BACKENDS) + "}",
                     help="where episodes run (default: process pool; serial runs in this process, where an agent "
                     "calling os._exit or crashing in native code ends the run, and one whose call never returns "
                     "hangs it)")
    run.add_argument("--workers", metavar="N", help="worker processes / Ray CPUs >= 1 (default: CPU count)")
    run.add_argument("--address", help="Ray cluster address for --backend ray: auto, HOST:PORT or ray://HOST:PORT "
                     "(default: start a local instance)")
    run.add_argument("--timeout", metavar="SECONDS", help="seconds > 0 per episode before it is recorded as timeout "
                     "(default: the suite's, 600)")
    run.add_argument("--memory-limit-mb", metavar="N", help="MiB of memory each episode's worker may allocate beyond what "
                     "it started with; past it the episode is recorded failed and the worker replaced (process backend "
                     "only; default: no limit)")
    run.add_argument("--out", default="runs/main", help="run folder (default: runs/main)")
    run.add_argument("--resume", action="store_true", help="finish an interrupted run in --out (with no settings flags: "
                     "the settings stored in its run.json)")
    run.add_argument("--no-report", action="store_true", help="skip writing the report")
    run.add_argument("--bound-as", "--floor-as", dest="bound_as", action="append", metavar="AGENT=BUILTIN",
                     help="in the regression suites, hold --agent AGENT to the calibrated success bound of the "
                     "built-in agent BUILTIN, repeatable (e.g. mypkg.agents:MyPusher=map-pusher); --floor-as is its "
                     "old name, still accepted")
    run.add_argument("--fail-fast", action="store_true",
                     help="in the regression suites, stop the run as soon as an agent's calibrated bound is certainly "
                     "broken (a crash, or a lower bound its remaining episodes can no longer reach); --resume finishes it")
    run.add_argument("--record", default="failures", metavar="{failures,all,none}",
                     help="episode recordings in OUT/replays/ (camera frames, poses, actions, the map's answers; "
                     "H.264 videos that play in any browser): failures (default: every failed episode, plus the "
                     "first successful one of each suite and agent to compare them with), all or none")
    run.set_defaults(func=cmd_run)

    cmp_ = sub.add_parser("compare", help="paired comparison of two agents on the same episodes")
    cmp_.add_argument("runs", nargs="+", help="run folders")
    cmp_.add_argument("--a", required=True, help="agent label A")
    cmp_.add_argument("--b", required=True, help="agent label B")
    cmp_.add_argument("--metric", default="success")
    cmp_.add_argument("--suite")
    cmp_.set_defaults(func=cmd_compare)

    rep = sub.add_parser("report", help="write the Markdown and HTML reports (tables, CIs, plots, episodes) for run folders",
                         description="Write RUN/report/report.md with its PNG figures and report.html (one self-contained "
                         "page: sortable tables, figures inline, one row per episode linking its replay video and map). "
                         "Several run folders are compared side by side.")
    rep.add_argument("runs", nargs="+", help="run folders")
    rep.add_argument("--out", help="report folder (default: RUN/report)")
    rep.add_argument("--bundle", nargs="?", const="", default=None, metavar="PATH",
                     help="write a portable report instead: one folder (default: RUN/report-bundle; PATH ending .zip: "
                     "that folder less .zip, and the zip of it) with report.html, report.md, the figures, the failure "
                     "pages and a copy of every replay video they link, all links inside it")
    rep.add_argument("--results-page", metavar="PATH",
                     help="write the documentation's results page instead (docs/results.md): the sealed headline "
                     "recomputed from the shipped records, then the runs' report tables, no figures or episode rows")
    rep.add_argument("--bundle-maps", action="store_true",
                     help="copy the final maps into the bundle too (hundreds of MB; without it a map cell gives the "
                     "command that opens it from the run folder)")
    rep.set_defaults(func=cmd_report)

    rpl = sub.add_parser(
        "replay", help="render an episode's recording to a video (camera beside a top-down view)",
        description="Render the recording of one episode of a run (RUN/replays/, written by cfharness run --record) "
        "to a video: the goal, the agent's camera beside a top-down view with the floor plan or table, the path so far, "
        "the distance to success and what the map answered, the outcome and why the episode stopped. H.264 MP4 "
        "through PyAV (plays in any browser); a GIF when PyAV is missing.",
        epilog="examples:\n  cfharness replay runs/main search-v1-0007\n"
        "  cfharness replay runs/main search-v1-0007 --agent map-navigator --out nav.mp4\n"
        "  cfharness replay runs/main runs/main/replays/search__map-navigator__search-v1-0007__s0.npz",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    rpl.add_argument("run", help="run folder")
    rpl.add_argument("episode", help="episode id, or the path of a recording (.npz)")
    rpl.add_argument("--suite", help="the episode's suite, when several suites recorded it")
    rpl.add_argument("--agent", help="the agent (name or label), when several agents recorded the episode")
    rpl.add_argument("--seed", type=int, help="the episode seed, when several seeds recorded it")
    rpl.add_argument("--out", help="video file, .mp4 or .gif (default: beside the recording)")
    rpl.add_argument("--fps", type=float, help="frames per second (default: 4 for search, 1 for tabletop pushes)")
    rpl.set_defaults(func=cmd_replay)

    lst = sub.add_parser("list", help="list suites, agents and encoders")
    lst.add_argument("--import", dest="plugin", action="append", metavar="MODULE",
                     help="import MODULE first (repeatable): its registered agents and encoders are listed too")
    lst.set_defaults(func=cmd_list)
