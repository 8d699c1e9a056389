"""Agent development on calibration episodes: where agent settings are chosen, never reported.

An agent's settings (a rule, a threshold, an option's default) are chosen on episodes that no
evaluation suite runs: the calibration episodes drawn like the suite's own
(:data:`DEVELOPMENT_EPISODES`; ``scenes/calibration-v2/`` for ``search-v2`` and ``rearrange-v2``). This runs a suite's
agents over them with the suite's environment settings and default perception, appending one
record per episode to ``OUT/results.jsonl`` (an interrupted run resumes there), and prints each
agent's success::

    python -m harness.runner.develop --suite search-v2 --agent map-navigator --out runs/develop/nav
    python -m harness.runner.develop --suite search-v2 --agent map-navigator \\
        --agent-option stuck_steps=3 --out runs/develop/nav-bump --workers 2

Results on these episodes decide settings; the figures a README or model card reports come from
the evaluation suites.
"""

from __future__ import annotations

import argparse
import sys
import uuid
from pathlib import Path

from conceptfusion.errors import HarnessError
from harness.runner.results import latest_records, record_key
from harness.runner.run import RunConfig, episode_jobs, run_missing_jobs
from harness.runner.suites import SCENES_ROOT, Suite, get_suite, suite_over

__all__ = ["DEVELOPMENT_EPISODES", "development_suite", "develop", "main"]

DEVELOPMENT_EPISODES: dict[str, str] = {
    "search-v2": "calibration-v2/search-episodes-v2.jsonl",
    "rearrange-v2": "calibration-v2/rearrange-episodes-v2.jsonl",
}
"""Suite -> its development episodes (relative to ``scenes/``): same generators as the suite's
episodes, calibration seeds only."""


def development_suite(name: str) -> Suite:
    """Suite ``name`` over its development episodes (all of them), named ``<name>-develop``.

    Raises:
        HarnessError: the suite has no development episodes.
    """
    if name not in DEVELOPMENT_EPISODES:
        raise HarnessError(f"--suite: expected a suite with development episodes ({', '.join(DEVELOPMENT_EPISODES)}), got {name!r}")
    return suite_over(get_suite(name), f"{name}-develop", SCENES_ROOT / DEVELOPMENT_EPISODES[name])


def develop(suite_name: str, out: str | Path, *, agents: tuple[str, ...] | None = None, agent_kwargs: dict | None = None,
            encoder: str | None = None, limit: int | None = None, workers: int | None = None,
            backend: str = "process", progress: bool = True) -> dict[str, tuple[int, int]]:
    """Run ``agents`` (default: the suite's) over the development episodes of ``suite_name``
    into ``out/results.jsonl`` (resuming what is there); returns agent -> (successes, episodes)
    over the records of this configuration."""
    suite = development_suite(suite_name)
    config = RunConfig(suites=(suite_name,), agents=agents, agent_kwargs=dict(agent_kwargs or {}), encoder=encoder,
                       limit=limit, backend=backend, workers=workers)
    jobs = episode_jobs(suite, config, uuid.uuid4().hex[:12])
    results = Path(out) / "results.jsonl"
    results.parent.mkdir(parents=True, exist_ok=True)
    wanted = {record_key(j.key_record()) for j in jobs}
    records = [r for r in latest_records(run_missing_jobs(jobs, results, backend=backend, workers=workers, progress=progress))
               if record_key(r) in wanted]
    summary: dict[str, tuple[int, int]] = {}
    for agent in dict.fromkeys(j.agent for j in jobs):
        mine = [r for r in records if r["agent"] == agent]
        summary[agent] = (sum(bool(r["metrics"].get("success")) for r in mine), len(mine))
    return summary


def main(argv: list[str] | None = None) -> int:
    from harness.commands import parse_agent_options

    parser = argparse.ArgumentParser(prog="python -m harness.runner.develop", description=__doc__.split("\n\n")[0])
    parser.add_argument("--suite", required=True, help=f"suite whose development episodes to run ({', '.join(DEVELOPMENT_EPISODES)})")
    parser.add_argument("--agent", action="append", help="agent, repeatable (default: the suite's)")
    parser.add_argument("--agent-option", action="append", metavar="KEY=VALUE", help="agent option, repeatable")
    parser.add_argument("--encoder", default=None, help="perception (default: the suite's)")
    parser.add_argument("--limit", type=int, default=None, help="first N episodes")
    parser.add_argument("--workers", type=int, default=None, help="worker processes (default: CPU count)")
    parser.add_argument("--out", required=True, help="folder of results.jsonl (resumed when it exists)")
    args = parser.parse_args(argv)
    try:
        summary = develop(args.suite, args.out, agents=tuple(args.agent) if args.agent else None,
                          agent_kwargs=parse_agent_options(args.agent_option), encoder=args.encoder,
                          limit=args.limit, workers=args.workers)
    except (HarnessError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    for agent, (k, n) in summary.items():
        print(f"{agent}: {k}/{n} successes")
    return 0


if __name__ == "__main__":
    sys.exit(main())
