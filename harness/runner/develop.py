"""Agent development on calibration and validation episodes: where agent settings are chosen, never reported.

An agent's settings (a rule, a threshold, an option's default) are chosen on episodes that no
evaluation suite runs (:data:`DEVELOPMENT_EPISODES`):

- ``calibration``: drawn like the suite's own on ``calibration`` seeds, targets TRAIN instances
  (``scenes/calibration-v2/``, for ``search-v2`` and ``rearrange-v2``);
- ``validation``: tables and apartments on ``tower_val`` seeds whose every target or goal is a
  VAL instance, a held-out instance of a trained category or a validation category
  (``scenes/validation-v2/``, for both): the open-world side of the evaluation episodes without
  their test objects;
- ``dev2``: the first evaluation episodes (``scenes/tabletop-v2/``, ``scenes/household-v2/``),
  which earlier choices were read on; a second development set since the sealed test set
  (``scenes/sealed-v2/``) took their role.

No development run may read the sealed test set: :func:`development_suite` refuses any sealed
episode (:func:`~sim_envs.scenes.sealed.refuse_sealed`).

This runs a suite's agents over one set with the suite's environment settings and default
perception, appending one record per episode to ``OUT/results.jsonl`` (an interrupted run resumes
there), and prints each agent's success::

    python -m harness.runner.develop --suite search-v2 --agent map-navigator --out runs/develop/nav
    python -m harness.runner.develop --suite search-v2 --agent map-navigator \\
        --agent-option presume_after=0 --out runs/develop/nav-no-presume --workers 2
    python -m harness.runner.develop --suite rearrange-v2 --episodes validation --out runs/develop/push-val
    python -m harness.runner.develop --suite search-v2 --env-option width=320 \\
        --env-option height=240 --out runs/develop/nav-320

``--env-option`` changes one of the suite's environment settings (a camera's resolution, a scan's
frame count) for the development run only, so that a change of the suite's settings is chosen
here too.

Results on these episodes decide settings; the figures a README or model card reports come from
the evaluation suites.
"""

from __future__ import annotations

import argparse
import dataclasses
import inspect
import json
import sys
import uuid
from pathlib import Path

from conceptfusion.errors import HarnessError
from harness.runner.results import latest_records, record_key
from harness.runner.run import RunConfig, episode_jobs, run_missing_jobs
from harness.runner.suites import SCENES_ROOT, Suite, get_suite, suite_over
from sim_envs.scenes.sealed import refuse_sealed_episodes

__all__ = ["DEVELOPMENT_EPISODES", "SET_SUFFIX", "development_suite", "develop", "parse_env_options", "main"]

DEVELOPMENT_EPISODES: dict[str, dict[str, str]] = {
    "search-v2": {"calibration": "calibration-v2/search-episodes-v2.jsonl",
                  "validation": "validation-v2/search-episodes-v2.jsonl",
                  "dev2": "household-v2/episodes-v2.jsonl"},
    "chain-v2": {"calibration": "calibration-v2/chain-episodes-v2.jsonl"},
    "instruct-v2": {"calibration": "calibration-v2/instruct-episodes-v2.jsonl"},
    "fetch-v2": {"calibration": "calibration-v2/fetch-episodes-v2.jsonl"},
    "rearrange-v2": {"calibration": "calibration-v2/rearrange-episodes-v2.jsonl",
                     "validation": "validation-v2/rearrange-episodes-v2.jsonl",
                     "dev2": "tabletop-v2/episodes-v2.jsonl"},
}
"""Suite -> set -> its development episodes (relative to ``scenes/``): same generators as the
suite's episodes, calibration or ``tower_val`` seeds only."""

SET_SUFFIX = {"calibration": "develop", "validation": "validation", "dev2": "dev2"}
"""Set -> the suffix of the development suite's name (``rearrange-v2-validation``)."""


def development_suite(name: str, env_kwargs: dict | None = None, episodes: str = "calibration") -> Suite:
    """Suite ``name`` over every episode of one development set, named ``<name>-develop``
    (calibration) or ``<name>-validation``, with ``env_kwargs`` replacing the suite's environment
    settings of the same names; the name then carries them
    (``search-v2-develop@height=240,width=320``), so that records of different settings never
    resume one another.

    Raises:
        HarnessError: the suite or the set has no development episodes, or an environment setting
            is not a keyword of the suite's environment.
    """
    if name not in DEVELOPMENT_EPISODES:
        raise HarnessError(f"--suite: expected a suite with development episodes ({', '.join(DEVELOPMENT_EPISODES)}), got {name!r}")
    if episodes not in DEVELOPMENT_EPISODES[name]:
        raise HarnessError(f"--episodes: expected one of {', '.join(DEVELOPMENT_EPISODES[name])} for {name}, got {episodes!r}")
    path = SCENES_ROOT / DEVELOPMENT_EPISODES[name][episodes]
    refuse_sealed_episodes(path, "python -m harness.runner.develop")
    suite = suite_over(get_suite(name), f"{name}-{SET_SUFFIX[episodes]}", path)
    if env_kwargs:
        accepted = _env_keywords(suite.task)
        unknown = sorted(set(env_kwargs) - accepted)
        if unknown:
            raise HarnessError(f"--env-option: {', '.join(unknown)} is not a setting of the {suite.task} environment; "
                               f"expected one of {', '.join(sorted(accepted))}")
        settings = ",".join(f"{k}={json.dumps(env_kwargs[k])}" for k in sorted(env_kwargs))
        suite = dataclasses.replace(suite, name=f"{suite.name}@{settings}", env_kwargs={**suite.env_kwargs, **env_kwargs})
    return suite


def _env_keywords(task: str) -> set[str]:
    """Keyword arguments the environment of ``task`` accepts, less those the runner sets itself."""
    from sim_envs.envs.object_search import ObjectSearchEnv
    from sim_envs.envs.tabletop_rearrange import TabletopRearrangeEnv

    env_class = {"object_search": ObjectSearchEnv, "tabletop_rearrange": TabletopRearrangeEnv}[task]
    params = inspect.signature(env_class.__init__).parameters
    return {k for k, p in params.items() if p.kind is p.KEYWORD_ONLY} - {"episodes", "render_mode", "scenes_root"}


def parse_env_options(items: list[str] | None) -> dict:
    """``--env-option KEY=VALUE`` items as a dict; each value is read as JSON (``320``, ``true``,
    ``0.5``) and kept as a string when it is not JSON. A malformed item, or a key given twice with
    different values, is a ``ValueError``."""
    from harness.commands import parse_agent_options

    out = {}
    for key, value in parse_agent_options(items, flag="--env-option").items():
        try:
            out[key] = json.loads(value)
        except json.JSONDecodeError:
            out[key] = value
    return out


def develop(suite_name: str, out: str | Path, *, agents: tuple[str, ...] | None = None, agent_kwargs: dict | None = None,
            encoder: str | None = None, limit: int | None = None, workers: int | None = None,
            backend: str = "process", progress: bool = True, env_kwargs: dict | None = None,
            episodes: str = "calibration") -> dict[str, tuple[int, int]]:
    """Run ``agents`` (default: the suite's) over the development set ``episodes`` of
    ``suite_name`` (with ``env_kwargs`` over the suite's environment settings) into
    ``out/results.jsonl`` (resuming what is there); returns agent -> (successes, episodes) over
    the records of this configuration."""
    suite = development_suite(suite_name, env_kwargs, episodes)
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
    parser.add_argument("--episodes", default="calibration", choices=tuple(SET_SUFFIX),
                        help="development set: calibration (trained instances), validation (VAL instances) or dev2 (the first evaluation "
                             "episodes)")
    parser.add_argument("--env-option", action="append", metavar="KEY=VALUE",
                        help="environment setting over the suite's (e.g. width=320), repeatable")
    parser.add_argument("--limit", type=int, default=None, help="first N episodes")
    parser.add_argument("--workers", type=int, default=None, help="worker processes (default: CPU count)")
    parser.add_argument("--out", required=True, help="folder of results.jsonl (resumed when it exists)")
    args = parser.parse_args(argv)
    try:
        summary = develop(args.suite, args.out, agents=tuple(args.agent) if args.agent else None,
                          agent_kwargs=parse_agent_options(args.agent_option), encoder=args.encoder,
                          limit=args.limit, workers=args.workers, env_kwargs=parse_env_options(args.env_option),
                          episodes=args.episodes)
    except (HarnessError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    for agent, (k, n) in summary.items():
        print(f"{agent}: {k}/{n} successes")
    return 0


if __name__ == "__main__":
    sys.exit(main())
