"""Running suites: jobs for every suite, resume, progress with ETA, results on disk.

Every suite becomes :class:`~harness.runner.jobs.Job` s (episode suites: episodes x agents, see
:func:`episode_jobs`; map suites: :func:`harness.runner.map_jobs.map_suite_jobs`), and all of
them go to one backend through :func:`harness.runner.backends.run_jobs`.

A run lives in a folder: ``run.json`` (its settings) and ``results.jsonl`` (one record per
episode or map case, appended as each finishes, so an interrupted run loses at most the jobs in
flight). One run at a time holds the folder (:mod:`harness.runner.folder`, an OS lock released
when the process ends): another process's run on it is refused. ``resume=True`` repairs a
half-written last line, checks the settings match and that every record is this run's (one
outcome per episode), and runs only the jobs without a record.

Settings are checked when a :class:`RunConfig` is made
(:func:`~harness.runner.settings.validate_run_config`): names
(suites, agents, encoder, backend, option keys, with the nearest valid ones), option values,
counts, seeds and the timeout; every problem is a :class:`~conceptfusion.errors.HarnessError`
(a ``ValueError``) whose message starts with the command-line flag of the setting
(``--limit: expected an integer >= 1, got -148``). :func:`plan_run` then builds every job and
checks that the backend is reachable (a bounded connect) before anything is written to the run
folder.
"""

from __future__ import annotations

import sys
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from agents.registry import AGENTS, resolve_agent
from harness.runner.backends import check_backend, run_jobs
from harness.runner.folder import RunLock, check_run_folder, lock_run_folder, refuse_if_busy, writing
from harness.runner.jobs import Job, import_plugins
from harness.runner.map_jobs import map_suite_jobs
from harness.runner.results import (
    RUN_CONFIG_FILE, agent_label, append_record, check_run_records, completed_keys, load_results, read_run_config,
    record_key, repair_results, write_run_config,
)
from harness.runner.settings import accepts_keyword, check_agent, validate_run_config
from harness.runner.suites import Suite, get_suite, suite_encoder, suite_episodes
from harness.runner.tasks import EpisodeJob

__all__ = ["RunConfig", "RunPlan", "plan_run", "episode_jobs", "suite_jobs", "run_suites", "run_missing_jobs", "Progress"]


@dataclass(frozen=True)
class RunConfig:
    """What a run does; stored in ``run.json`` so ``--resume`` continues the same run.

    Every field is checked on construction (:func:`validate_run_config`); the command-line flag
    of each field is given in brackets, and error messages name the flag.
    """

    suites: tuple[str, ...]
    """Suite names (``--suite``), at least one, each once."""
    agents: tuple[str, ...] | None = None
    """Agents per episode suite (``--agent``; None: each suite's defaults): registered names or
    ``"module:Class"`` import paths, each fitting every episode suite of the run."""
    encoder: str | None = None
    """Perception for the map-using agents and the map suites (``--encoder``): an encoder spec
    (:class:`~conceptfusion.perception.featurizer.PerceptionSpec`, accepted too and stored as its
    string); an unknown name fails here, naming the nearest ones. None: each suite's default, the
    shipped tower of its world (:func:`~harness.runner.suites.suite_encoder`)."""
    agent_kwargs: dict = field(default_factory=dict)
    """Extra options (``--agent-option KEY=VALUE``) for every agent that accepts them (e.g.
    ``{"integrate_every": 2}``) and for the map suites
    (:data:`~harness.runner.settings.MAP_SUITE_OPTIONS`). A key that no
    agent or suite of the run accepts, or a value out of an option's range, is refused; the
    values are stored as given (command-line strings stay strings)."""
    limit: int | None = None
    """First N >= 1 episodes of each suite (``--limit``; None: the suite's own limit, or all)."""
    seed: int = 0
    """Episode seed >= 0 (``--seed``)."""
    seeds: int = 1
    """Seeds per episode >= 1 (``--seeds``): every episode (and map-suite scene) runs with seeds
    ``seed, seed + 1, ..., seed + seeds - 1``, one record each (records are keyed by seed), so
    that the report can give the between-seed spread of each agent's success."""
    backend: str = "process"
    """``--backend``: one of :data:`~harness.runner.backends.BACKENDS`."""
    workers: int | None = None
    """Worker processes / Ray CPUs >= 1 (``--workers``; None: the CPU count)."""
    address: str | None = None
    """Ray cluster address (``--address``; only with ``backend="ray"``)."""
    timeout_s: float | None = None
    """Seconds > 0 per episode before it is recorded as ``timeout`` (``--timeout``; None: the suite's)."""
    memory_limit_mb: int | None = None
    """MiB >= 1 of memory each episode's worker may allocate beyond what it started with
    (``--memory-limit-mb``; None: no limit); past it the episode is recorded ``failed`` ("memory limit of N MiB exceeded") and
    its worker replaced. Only with ``backend="process"`` (see
    :mod:`harness.runner.process_pool`, which says how memory is measured and why). Like the
    backend, not part of the settings a resumed run must match."""
    plugins: tuple[str, ...] = ()
    """Modules imported (in every worker too) before agents are built (``--import``): they register
    agents by name with :func:`agents.registry.register_agent`."""
    record: str = "failures"
    """Episode recordings (``--record``): ``"failures"`` (the episodes that failed, and the first
    successful one of each suite and agent to compare them with), ``"all"`` or ``"none"``; written
    to ``RUN/replays/`` (:mod:`harness.replay`). Stored in ``run.json`` beside
    the settings, not in them: results do not depend on it, and a run may resume with another."""

    def __post_init__(self) -> None:
        validate_run_config(self)

    def settings(self) -> dict:
        """The part that must match on resume (not the backend: results do not depend on it)."""
        return {
            "suites": list(self.suites), "agents": list(self.agents) if self.agents else None, "encoder": self.encoder,
            "agent_kwargs": dict(self.agent_kwargs), "limit": self.limit, "seed": self.seed,
            **({"seeds": self.seeds} if self.seeds != 1 else {}),  # absent at 1: a run.json of before resumes
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
    spec = AGENTS.get(agent)
    if spec is None:  # a user agent given by import path: the options it takes, and the encoder if it takes one
        factory = resolve_agent(agent)  # an unimportable path fails here, before any episode runs
        kw = {k: v for k, v in extra.items() if accepts_keyword(factory, k)}
        if accepts_keyword(factory, "encoder", unknown=False):
            kw.setdefault("encoder", encoder)
        return kw
    kw = {k: v for k, v in extra.items() if k in spec.kwargs}
    if "encoder" in spec.kwargs:
        kw["encoder"] = encoder
    return kw


def episode_jobs(suite: Suite, config: RunConfig, run_id: str, *, out_dir: str | Path | None = None) -> list[EpisodeJob]:
    """Jobs of an episode suite: every (agent, episode, seed) triple, agents in order, then
    episodes (of :func:`~harness.runner.suites.suite_episodes`, which leaves out reserved scenes:
    the first ``config.limit``, else the suite's ``agent_limits`` for the agent, else its
    ``limit``), then the ``config.seeds`` seeds from ``config.seed``. With ``out_dir`` (the run
    folder) the jobs record episodes as ``config.record`` says into ``out_dir/replays/``; without
    it they record nothing."""
    import_plugins(config.plugins)
    out = None if out_dir is None else str(Path(out_dir).resolve())
    all_episodes = suite_episodes(suite)
    agents = config.agents or suite.agents
    jobs = []
    for agent in agents:
        check_agent(agent, suite)
        kw = _agent_kwargs_for(agent, suite_encoder(suite, config.encoder), config.agent_kwargs)
        limit = config.limit if config.limit is not None else suite.agent_limits.get(agent, suite.limit)
        episodes = all_episodes if limit is None else all_episodes[:limit]
        for ep in episodes:
            for seed in range(config.seed, config.seed + config.seeds):
                jobs.append(EpisodeJob(
                    run_id=run_id, suite=suite.name, task=suite.task, agent=agent, agent_kwargs=kw, episode=ep,
                    seed=seed, env_kwargs=dict(suite.env_kwargs), timeout_s=float(config.timeout_s or suite.timeout_s),
                    plugins=tuple(config.plugins), record=config.record if out_dir is not None else "none", out_dir=out,
                ))
    return jobs


def _map_jobs(suite: Suite, config: RunConfig, run_id: str, run_dir: Path) -> list[Job]:
    return map_suite_jobs(suite.name, config, run_id, out_dir=run_dir)


def _episode_jobs(suite: Suite, config: RunConfig, run_id: str, run_dir: Path) -> list[Job]:
    return episode_jobs(suite, config, run_id, out_dir=run_dir)


_JOB_BUILDERS = {"episodes": _episode_jobs, "maps": _map_jobs}
"""Suite kind -> ``(suite, config, run_id, run_dir) -> jobs``."""


def suite_jobs(suite: Suite, config: RunConfig, run_id: str, run_dir: str | Path) -> list[Job]:
    """The jobs of one suite of any kind; side files (map suites) go into ``run_dir``."""
    return _JOB_BUILDERS[suite.kind](suite, config, run_id, Path(run_dir))


@dataclass
class RunPlan:
    """A run ready to go (see :func:`plan_run`): its settings, folder, id and the jobs still to do."""

    config: RunConfig
    run_dir: Path
    run_id: str
    jobs: list[Job]
    """Every job of the run, in order."""
    todo: list[Job]
    """The jobs without a record yet (all of them for a new run)."""
    lock: RunLock | None = None
    """This process's hold on ``run_dir`` (:func:`~harness.runner.folder.lock_run_folder`), until :meth:`close`."""

    def close(self) -> None:
        """Give up the run folder, so another process's run may take it (the end of the process does too)."""
        if self.lock is not None:
            self.lock.release()

    @property
    def results(self) -> Path:
        return self.run_dir / "results.jsonl"

    def execute(self, *, on_record: Callable[[dict], None] | None = None, progress: bool = True,
                stop: Callable[[dict], bool] | None = None) -> list[dict]:
        """Run the jobs still to do on the config's backend, appending each record as it comes;
        returns all records of the run. ``stop`` (called with each new record after it is
        written) ends the run early when it returns True: the jobs in flight are stopped and the
        rest left undone, so ``resume`` can finish the run later. A record that cannot be written
        because the disk is full (or over quota, or read-only) stops the run the same way, raising
        :class:`~harness.runner.folder.RunFolderFullError`; the file keeps whole records only
        (:func:`~harness.runner.results.append_record`), and ``resume`` runs that episode again."""
        config = self.config
        bar = Progress(len(self.todo), "+".join(config.suites)) if progress and self.todo else None
        records = run_jobs(self.todo, backend=config.backend, workers=config.workers, address=config.address,
                           memory_limit_mb=config.memory_limit_mb)
        try:
            for rec in records:
                with writing("a results record", self.results):
                    append_record(self.results, rec)
                if on_record:
                    on_record(rec)
                if bar:
                    bar.update(_progress_note(rec))
                if stop is not None and stop(rec):
                    break
        finally:
            close = getattr(records, "close", None)
            if close is not None:  # a generator backend: stop its workers now
                close()
        return load_results(self.results)


def plan_run(config: RunConfig, run_dir: str | Path, *, resume: bool = False) -> RunPlan:
    """Prepare a run: check the folder (:func:`~harness.runner.folder.check_run_folder`) and that no
    other process's run holds it, build every job (a bad agent or option fails here), check that
    the backend is reachable (:func:`~harness.runner.backends.check_backend`, a bounded connect),
    and only then take the folder (:func:`~harness.runner.folder.lock_run_folder`, held until
    :meth:`RunPlan.close`) and write ``run.json`` (or, with ``resume``, repair a half-written last
    line of the results and check that every record belongs to this run:
    :func:`~harness.runner.results.check_run_records`).

    A folder whose run never recorded a result (a start that failed or was stopped early) is
    started afresh: its ``run.json`` is replaced.

    Raises:
        FileExistsError: ``run_dir`` holds results and ``resume`` is False.
        ValueError: ``resume`` with settings other than the stored ones; an ``--out`` that cannot
            be a run folder; a folder another process's run holds
            (:class:`~harness.runner.folder.RunFolderBusyError`); with ``resume``, a results file
            with another run's records or two different outcomes of one episode.
        FileNotFoundError: ``resume`` in a folder without ``run.json``.
        RayUnavailableError: the Ray backend is not installed or its cluster does not answer.
        RunFolderFullError: the lock file, ``run.json`` or the repair of the results cannot be
            written: the file system is full, over quota or read-only.
    """
    run_dir = check_run_folder(run_dir)
    refuse_if_busy(run_dir)
    results = run_dir / "results.jsonl"
    suites = [get_suite(s) for s in config.suites]
    if resume:
        run_id = _stored_run_id(config, run_dir)
    else:
        _refuse_results(run_dir)
        run_id = uuid.uuid4().hex[:12]
    jobs = [job for suite in suites for job in suite_jobs(suite, config, run_id, run_dir)]
    check_backend(config.backend, config.address, workers=config.workers)
    lock = lock_run_folder(run_dir, run_id)
    try:  # again, now that no other run can change the folder
        if resume:
            if _stored_run_id(config, run_dir) != run_id:
                raise ValueError(f"{run_dir}: its run.json changed while this run was being planned; resume again")
            with writing("results.jsonl, cutting its half-written last line", results):
                repair_results(results)
            check_run_records(results, run_id)
        else:
            _refuse_results(run_dir)
            with writing("run.json", run_dir / RUN_CONFIG_FILE):
                write_run_config(run_dir, {"run_id": run_id, "settings": config.settings(), "backend": config.backend,
                                           "record": config.record}, overwrite=True)
        done = completed_keys(load_results(results))
    except BaseException:
        lock.release()
        raise
    todo = [j for j in jobs if record_key(j.key_record()) not in done]
    return RunPlan(config, run_dir, run_id, jobs, todo, lock)


def _stored_run_id(config: RunConfig, run_dir: Path) -> str:
    """The run id in ``run_dir/run.json``, once its settings are ``config``'s (a ``ValueError`` otherwise)."""
    stored = read_run_config(run_dir)
    if stored.get("settings") != config.settings():
        raise ValueError(f"{run_dir}: --resume expects the settings the run started with: {stored.get('settings')}, got {config.settings()}")
    return stored["run_id"]


def _refuse_results(run_dir: Path) -> None:
    results = run_dir / "results.jsonl"
    if results.exists() and results.stat().st_size > 0:
        raise FileExistsError(f"{run_dir} already holds results; use --resume to finish it or choose another --out")


def run_missing_jobs(jobs: list[Job], results: str | Path, *, backend: str = "process", workers: int | None = None,
                     progress: bool = True) -> list[dict]:
    """Run the ``jobs`` that have no record in ``results`` yet (an interrupted run resumes),
    appending each record as it comes, with one progress line per record on stderr; returns
    every record of the file. For runs outside a run folder (floor calibrations, development
    runs on calibration episodes)."""
    done = completed_keys(load_results(results))
    todo = [j for j in jobs if record_key(j.key_record()) not in done]
    for i, rec in enumerate(run_jobs(todo, backend=backend, workers=workers), start=1):
        append_record(results, rec)
        if progress:
            print(f"[{i}/{len(todo)}] {rec['suite']} {rec['agent']} {rec['episode_id']} {rec['status']} "
                  f"success={rec['metrics'].get('success')} {rec['timings'].get('wall_s', 0):.1f}s", file=sys.stderr)
    return load_results(results)


def run_suites(
    config: RunConfig, run_dir: str | Path, *, resume: bool = False, on_record: Callable[[dict], None] | None = None,
    progress: bool = True,
) -> list[dict]:
    """Run every suite of ``config`` into ``run_dir``; returns all records of the run.

    The jobs of all suites (episode and map suites alike) are built first, so that a bad agent
    name fails before any work, then run together on ``config.backend`` (:func:`plan_run`, then
    :meth:`RunPlan.execute`).
    """
    plan = plan_run(config, run_dir, resume=resume)
    try:
        return plan.execute(on_record=on_record, progress=progress)
    finally:
        plan.close()


def _progress_note(rec: dict) -> str:
    if rec["status"] != "ok":
        outcome = rec["status"]
    elif "success" in rec["metrics"]:
        outcome = "ok" if rec["metrics"]["success"] else "fail"
    else:  # map suites score without a success flag
        outcome = "ok"
    return f"{rec['suite']} {agent_label(rec['agent'], rec['agent_kwargs'])} {rec['episode_id']} [{rec['encoder']}] {outcome}"

