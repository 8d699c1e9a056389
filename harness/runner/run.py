"""Running suites: jobs for every suite, resume, progress with ETA, results on disk.

Every suite becomes :class:`~harness.runner.jobs.Job` s (episode suites: episodes x agents, see
:func:`episode_jobs`; map suites: :func:`harness.runner.map_jobs.map_suite_jobs`), and all of
them go to one backend through :func:`harness.runner.backends.run_jobs`.

A run lives in a folder: ``run.json`` (its settings) and ``results.jsonl`` (one record per
episode or map case, appended as each finishes, so an interrupted run loses at most the jobs in
flight). ``resume=True`` repairs a half-written last line, checks the settings match, and runs
only the jobs without a record.
"""

from __future__ import annotations

import sys
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from conceptfusion.names import unknown_name_error
from conceptfusion.perception.featurizer import PerceptionSpec
from harness.runner.backends import run_jobs
from harness.runner.jobs import Job, import_plugins
from harness.runner.map_jobs import map_suite_jobs
from harness.runner.results import (
    agent_label, append_record, completed_keys, load_results, read_run_config, record_key, repair_results, write_run_config,
)
from harness.runner.suites import Suite, get_suite
from harness.runner.tasks import EpisodeJob
from sim_envs.scenes.episodes import load_episodes

__all__ = ["RunConfig", "episode_jobs", "suite_jobs", "run_suites", "Progress"]


@dataclass(frozen=True)
class RunConfig:
    """What a run does; stored in ``run.json`` so ``--resume`` continues the same run."""

    suites: tuple[str, ...]
    agents: tuple[str, ...] | None = None
    """Agents per episode suite (None: each suite's defaults)."""
    encoder: str = "embedded"
    """Perception for the map-using agents and the map suites: an encoder spec
    (:class:`~conceptfusion.perception.featurizer.PerceptionSpec`, accepted too and stored as its
    string); an unknown name fails here, naming the nearest ones."""
    agent_kwargs: dict = field(default_factory=dict)
    """Extra options for every agent that accepts them (e.g. ``{"integrate_every": 2}``)."""
    limit: int | None = None
    """First N episodes of each suite (None: the suite's own limit, or all)."""
    seed: int = 0
    backend: str = "process"
    workers: int | None = None
    address: str | None = None
    timeout_s: float | None = None
    plugins: tuple[str, ...] = ()
    """Modules imported (in every worker too) before agents are built: they register agents by
    name with :func:`agents.registry.register_agent`."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "encoder", str(PerceptionSpec.parse(self.encoder)))

    def settings(self) -> dict:
        """The part that must match on resume (not the backend: results do not depend on it)."""
        return {
            "suites": list(self.suites), "agents": list(self.agents) if self.agents else None, "encoder": self.encoder,
            "agent_kwargs": dict(self.agent_kwargs), "limit": self.limit, "seed": self.seed,
            **({"plugins": list(self.plugins)} if self.plugins else {}),
        }


class Progress:
    """A one-line progress bar with ETA on stderr (plain lines when stderr is not a terminal)."""

    def __init__(self, total: int, label: str, stream=None) -> None:
        self.total, self.label, self.done, self.t0 = total, label, 0, time.monotonic()
        self.stream = stream or sys.stderr
        self.tty = hasattr(self.stream, "isatty") and self.stream.isatty()

    def update(self, note: str = "") -> None:
        self.done += 1
        el = time.monotonic() - self.t0
        eta = el / self.done * (self.total - self.done)
        width = 24
        fill = int(width * self.done / max(self.total, 1))
        line = f"{self.label} [{'#' * fill}{'.' * (width - fill)}] {self.done}/{self.total} {el:5.0f}s elapsed, ETA {eta:5.0f}s {note}"
        if self.tty:
            self.stream.write("\r" + line[:160].ljust(160))
            if self.done == self.total:
                self.stream.write("\n")
        else:
            self.stream.write(line + "\n")
        self.stream.flush()


def _agent_kwargs_for(agent: str, encoder: str, extra: dict) -> dict:
    import inspect

    from agents.registry import AGENTS, resolve_agent

    spec = AGENTS.get(agent)
    if spec is None:  # a user agent given by import path: every option, and the encoder if it takes one
        kw = dict(extra)
        factory = resolve_agent(agent)  # an unimportable path fails here, before any episode runs
        try:
            params = inspect.signature(factory).parameters
        except (TypeError, ValueError):  # a callable without a signature (some builtins)
            params = {}
        if "encoder" in params or any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values()):
            kw.setdefault("encoder", encoder)
        return kw
    kw = {k: v for k, v in extra.items() if k in spec.kwargs}
    if "encoder" in spec.kwargs:
        kw["encoder"] = encoder
    return kw


def episode_jobs(suite: Suite, config: RunConfig, run_id: str) -> list[EpisodeJob]:
    """Jobs of an episode suite: every (agent, episode) pair, agents in order."""
    import_plugins(config.plugins)
    episodes = load_episodes(suite.episodes_file).episodes
    limit = config.limit if config.limit is not None else suite.limit
    if limit is not None:
        episodes = episodes[:limit]
    agents = config.agents or suite.agents
    jobs = []
    for agent in agents:
        _check_agent(agent, suite)
        kw = _agent_kwargs_for(agent, suite.encoder or config.encoder, config.agent_kwargs)
        for ep in episodes:
            jobs.append(EpisodeJob(
                run_id=run_id, suite=suite.name, task=suite.task, agent=agent, agent_kwargs=kw, episode=ep,
                seed=config.seed, env_kwargs=dict(suite.env_kwargs), timeout_s=float(config.timeout_s or suite.timeout_s),
                plugins=tuple(config.plugins),
            ))
    return jobs


def _check_agent(agent: str, suite: Suite) -> None:
    from agents.registry import AGENTS, agent_names

    if agent in AGENTS:
        if AGENTS[agent].task not in (suite.task, "any"):
            raise ValueError(f"agent {agent!r} solves {AGENTS[agent].task}, not suite {suite.name!r} ({suite.task}); "
                             f"agents for it: {', '.join(agent_names(suite.task))}")
        return
    if ":" not in agent:
        raise unknown_name_error("agent", agent, AGENTS,
                                 listing=f"for suite {suite.name!r}: {', '.join(agent_names(suite.task))}; or 'module:Class'")


def _map_jobs(suite: Suite, config: RunConfig, run_id: str, run_dir: Path) -> list[Job]:
    return map_suite_jobs(suite.name, config, run_id, out_dir=run_dir)


def _episode_jobs(suite: Suite, config: RunConfig, run_id: str, run_dir: Path) -> list[Job]:
    return episode_jobs(suite, config, run_id)


_JOB_BUILDERS = {"episodes": _episode_jobs, "maps": _map_jobs}
"""Suite kind -> ``(suite, config, run_id, run_dir) -> jobs``."""


def suite_jobs(suite: Suite, config: RunConfig, run_id: str, run_dir: str | Path) -> list[Job]:
    """The jobs of one suite of any kind; side files (map suites) go into ``run_dir``."""
    return _JOB_BUILDERS[suite.kind](suite, config, run_id, Path(run_dir))


def run_suites(
    config: RunConfig, run_dir: str | Path, *, resume: bool = False, on_record: Callable[[dict], None] | None = None,
    progress: bool = True,
) -> list[dict]:
    """Run every suite of ``config`` into ``run_dir``; returns all records of the run.

    The jobs of all suites (episode and map suites alike) are built first, so that a bad agent
    name fails before any work, then run together on ``config.backend``.
    """
    run_dir = Path(run_dir)
    results = run_dir / "results.jsonl"
    suites = [get_suite(s) for s in config.suites]  # unknown names fail before any work
    if resume:
        stored = read_run_config(run_dir)
        if stored.get("settings") != config.settings():
            raise ValueError(f"{run_dir}: --resume expects the settings the run started with: {stored.get('settings')}, got {config.settings()}")
        run_id = stored["run_id"]
        repair_results(results)
    else:
        if results.exists() and results.stat().st_size > 0:
            raise FileExistsError(f"{run_dir} already holds results; use --resume to finish it or choose another --out")
        run_id = uuid.uuid4().hex[:12]
        write_run_config(run_dir, {"run_id": run_id, "settings": config.settings(), "backend": config.backend})
    done = completed_keys(load_results(results))
    jobs = [job for suite in suites for job in suite_jobs(suite, config, run_id, run_dir)]
    todo = [j for j in jobs if record_key(j.key_record()) not in done]
    bar = Progress(len(todo), "+".join(config.suites)) if progress and todo else None
    for rec in run_jobs(todo, backend=config.backend, workers=config.workers, address=config.address):
        append_record(results, rec)
        if on_record:
            on_record(rec)
        if bar:
            bar.update(_progress_note(rec))
    return load_results(results)


def _progress_note(rec: dict) -> str:
    if rec["status"] != "ok":
        outcome = rec["status"]
    elif "success" in rec["metrics"]:
        outcome = "ok" if rec["metrics"]["success"] else "fail"
    else:  # map suites score without a success flag
        outcome = "ok"
    return f"{rec['suite']} {agent_label(rec['agent'], rec['agent_kwargs'])} {rec['episode_id']} [{rec['encoder']}] {outcome}"

