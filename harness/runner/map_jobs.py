"""Map-suite jobs: one :class:`MapJob` per case of a map suite (:mod:`harness.maps.suites`).

A :class:`MapJob` is a :class:`~harness.runner.jobs.Job` like an episode: picklable, it runs on
any backend (in a worker process or a Ray task as well as here) and returns one record with
``episode_id`` = the scene id. Side files (the query suite's heatmap ``.npz``) go into the run
folder, given as an absolute path so that a worker in another directory writes to the same place.
"""

from __future__ import annotations

import logging
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path

from harness.maps.suites import MapCase, get_map_suite
from harness.runner.jobs import job_record, worker_thread_share
from harness.runner.suites import get_suite, suite_encoder

__all__ = ["MapJob", "map_suite_jobs", "run_map_job"]

_log = logging.getLogger(__name__)


@dataclass(frozen=True)
class MapJob:
    """One map-suite job: everything a worker needs, picklable (a :class:`~harness.runner.jobs.Job`)."""

    run_id: str
    suite: str
    agent: str
    """The method or variant (``"conceptfusion"``, an ablation variant, ``"map-3d"``, ``"frame-2.5d"``)."""
    encoder: str
    scene_id: str
    seed: int = 0
    options: dict = field(default_factory=dict)
    """Scan size and proposer overrides (stored as the record's ``agent_kwargs``)."""
    out_dir: str | None = None
    """Run folder for side files (the query suite's heatmap .npz); None: none written."""
    note: str = ""
    """Why the encoder differs from the run's, if it does."""
    timeout_s: float = 600.0
    """Wall-clock limit of the job on the process and Ray backends."""
    plugins: tuple[str, ...] = ()
    """Modules to import before the job runs (none needed by the map suites)."""

    @property
    def task(self) -> str:
        return get_map_suite(self.suite).task

    @property
    def episode_id(self) -> str:
        return self.scene_id

    @property
    def label(self) -> str:
        return f"{self.agent} {self.scene_id} [{self.encoder}]"

    @property
    def expected_s(self) -> float:
        """Rough length of the job in seconds (the backends start the longest jobs first)."""
        return {"query": 2.0, "query-v2": 2.0, "query-open": 10.0, "ablation": 0.5, "ablation-v2": 0.5, "spatial": 1.0,
                "spatial-v2": 1.0}.get(self.suite, 1.0)

    @property
    def case(self) -> MapCase:
        return MapCase(self.agent, self.encoder, self.scene_id, self.note)

    def key_record(self) -> dict:
        """The fields :func:`harness.runner.results.record_key` reads, as the job's record will have them."""
        return {"suite": self.suite, "agent": self.agent, "agent_kwargs": dict(self.options), "encoder": self.encoder,
                "episode_id": self.episode_id, "seed": self.seed}

    def run(self) -> list[dict]:
        """Run the job: its one record (see :func:`run_map_job`), with torch on this worker's
        share of the cores (:func:`~harness.runner.jobs.worker_thread_share`)."""
        with worker_thread_share():
            return run_map_job(self)

    def failure_record(self, status: str, error: str, wall_s: float) -> dict:
        """The record of the job when its worker timed out or died."""
        return job_record(self, status=status, error=error, timings={"wall_s": wall_s})


def map_suite_jobs(name: str, config, run_id: str, *, out_dir: str | Path | None = None) -> list[MapJob]:
    """Jobs of map suite ``name`` for a :class:`harness.runner.run.RunConfig` (``encoder``, ``limit``
    (scenes of each kind), ``seed`` and ``seeds`` (one job per seed), ``agent_kwargs`` (see :mod:`harness.maps.suites`),
    ``timeout_s`` (default: the suite's)); ``out_dir`` is the run folder for side files.

    Raises ``ValueError`` for a suite that is not a map suite, naming the nearest ones.
    """
    suite = get_map_suite(name)
    opts = {k: v for k, v in dict(config.agent_kwargs or {}).items() if k in suite.options}
    timeout_s = float(config.timeout_s or get_suite(name).timeout_s)
    out = None if out_dir is None else str(Path(out_dir).resolve())
    return [
        MapJob(run_id=str(run_id), suite=name, agent=c.agent, encoder=c.encoder, scene_id=c.scene_id, seed=seed,
               options=opts, out_dir=out, note=c.note, timeout_s=timeout_s)
        for c in suite.cases(suite_encoder(get_suite(name), config.encoder), config.limit)
        for seed in range(int(config.seed), int(config.seed) + int(config.seeds))
    ]


def run_map_job(job: MapJob) -> list[dict]:
    """Run one job; returns its one record (``status="failed"`` with the error if it raised).

    ``extras["heatmap_npz"]`` (query suite, when the job has an ``out_dir``) is the heatmap's
    path relative to ``out_dir``.
    """
    if not isinstance(job, MapJob):
        raise TypeError(f"run_map_job: expected a MapJob, got {type(job).__name__}")
    t0 = time.perf_counter()
    status, error, metrics, extras, timings = "ok", None, {}, {}, {}
    try:
        metrics, extras, timings = get_map_suite(job.suite).score(job.case, job.options, job.seed, job.out_dir)
    except Exception as exc:  # a broken scene or encoder becomes a failed record, not a stopped run
        _log.warning("map job %s failed: %s", job.label, exc)
        status, error = "failed", f"{type(exc).__name__}: {exc}\n{traceback.format_exc(limit=4)}"
    timings = {**timings, "wall_s": time.perf_counter() - t0}
    return [job_record(job, status=status, error=error, metrics=metrics, timings=timings, extras=extras)]
