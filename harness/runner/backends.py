"""Where jobs run: in this process, in a local pool of worker processes, or on a Ray cluster.

Every backend takes :class:`~harness.runner.jobs.Job` s (episode jobs and map jobs alike), calls
``job.run()`` and yields the result records as jobs finish (in completion order; records carry
their keys). Results do not depend on the backend: a job is a pure function of its fields
(scene, episode, seed, agent settings).

* ``serial``: one job after another in this process (debugging, tests); no timeouts;
* ``process`` (default): ``workers`` processes (default: the CPU count), started with the
  ``spawn`` method so no simulator or GL state is inherited. A job that runs past its
  ``timeout_s`` has its worker killed and is recorded as ``timeout``; a worker that dies (a crash
  in native code) is recorded as ``failed`` with its exit code (``job.failure_record``). Both
  are replaced and the run goes on. Each worker gets its share of the cores
  (:func:`~harness.runner.jobs.worker_thread_share`, used by the map jobs);
* ``ray``: ``ray.remote`` tasks on a cluster (``address="auto"`` or ``"ray://host:10001"``) or a
  local Ray instance (``address=None``); timeouts cancel the task. Needs the ``ray`` extra.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import queue
import signal
import time
from typing import Iterable, Iterator

from conceptfusion.errors import ConceptFusionError, HarnessError
from conceptfusion.names import did_you_mean
from harness.runner.jobs import WORKER_THREADS_ENV, Job

__all__ = ["BACKENDS", "run_jobs", "RayUnavailableError"]

BACKENDS = ("process", "serial", "ray")


class RayUnavailableError(ConceptFusionError, RuntimeError):
    """Ray is not installed or its cluster cannot be reached (a ``RuntimeError``, not a ``ValueError``:
    the commands that report bad settings with exit status 2 let it through as before)."""


def _run_job(job: Job) -> list[dict]:
    """What a worker runs for a job (module level, so that Ray ships it by reference)."""
    return job.run()


def _serial(jobs: list[Job]) -> Iterator[dict]:
    for job in jobs:
        yield from _run_job(job)


def _worker_main(inbox, outbox, threads: int) -> None:
    """Worker loop: run jobs until told to stop (``None``); ``threads`` is the worker's share of
    the cores, for the jobs that limit their threads to it."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent handles Ctrl-C
    os.environ[WORKER_THREADS_ENV] = str(threads)
    while True:
        item = inbox.get()
        if item is None:
            break
        index, job = item
        outbox.put((index, _run_job(job)))


class _Worker:
    def __init__(self, ctx, outbox, threads: int) -> None:
        self.inbox = ctx.Queue()
        self.proc = ctx.Process(target=_worker_main, args=(self.inbox, outbox, threads), daemon=True)
        self.proc.start()
        self.job: tuple[int, Job] | None = None
        self.started = 0.0

    def assign(self, index: int, job: Job) -> None:
        self.job, self.started = (index, job), time.monotonic()
        self.inbox.put((index, job))

    def kill(self) -> None:
        if self.proc.is_alive():
            self.proc.kill()
        self.proc.join(timeout=5)


def _process_pool(jobs: list[Job], workers: int) -> Iterator[dict]:
    ctx = mp.get_context("spawn")
    outbox = ctx.Queue()
    pending = list(enumerate(jobs))[::-1]
    size = max(1, min(workers, len(jobs)))
    threads = max(1, (os.cpu_count() or 1) // size)
    pool = [_Worker(ctx, outbox, threads) for _ in range(size)]
    done = 0
    try:
        while done < len(jobs):
            for w in pool:
                if w.job is None and pending:
                    w.assign(*pending.pop())
            try:
                index, records = outbox.get(timeout=0.5)
            except queue.Empty:
                index, records = None, None
            if records is not None:
                for w in pool:
                    if w.job is not None and w.job[0] == index:
                        w.job = None
                done += 1
                yield from records
            now = time.monotonic()
            for k, w in enumerate(pool):
                if w.job is None:
                    continue
                index, job = w.job
                elapsed = now - w.started
                if elapsed > job.timeout_s:
                    w.kill()
                    pool[k] = _Worker(ctx, outbox, threads)
                    done += 1
                    yield job.failure_record("timeout", f"episode exceeded {job.timeout_s:.0f} s; its worker was stopped", elapsed)
                elif not w.proc.is_alive():
                    code = w.proc.exitcode
                    pool[k] = _Worker(ctx, outbox, threads)
                    done += 1
                    yield job.failure_record("failed", f"worker process died (exit code {code}) during the episode", elapsed)
    finally:
        for w in pool:
            if w.proc.is_alive():
                w.inbox.put(None)
        for w in pool:
            w.proc.join(timeout=2)
            w.kill()


def _ray(jobs: list[Job], workers: int, address: str | None) -> Iterator[dict]:
    try:
        import ray
    except ImportError as exc:
        raise RayUnavailableError('the ray backend needs Ray: pip install -e ".[ray]"') from exc
    if not ray.is_initialized():
        try:
            if address:
                ray.init(address=address, ignore_reinit_error=True, log_to_driver=False)
            else:
                ray.init(num_cpus=max(1, workers), ignore_reinit_error=True, log_to_driver=False, include_dashboard=False)
        except Exception as exc:  # ConnectionError, RuntimeError ... depending on the Ray version
            raise RayUnavailableError(f"cannot reach the Ray cluster at {address or 'a new local instance'}: {exc}") from exc
    remote = ray.remote(num_cpus=1, max_retries=0)(_run_job)
    refs = {remote.remote(job): (job, time.monotonic()) for job in jobs}
    while refs:
        ready, _ = ray.wait(list(refs), num_returns=1, timeout=0.5)
        for ref in ready:
            job, t0 = refs.pop(ref)
            try:
                records = ray.get(ref)
            except Exception as exc:  # the task's process died
                records = [job.failure_record("failed", f"Ray task failed: {type(exc).__name__}: {exc}", time.monotonic() - t0)]
            yield from records
        now = time.monotonic()
        for ref, (job, t0) in list(refs.items()):
            if now - t0 > job.timeout_s:
                ray.cancel(ref, force=True)
                refs.pop(ref)
                yield job.failure_record("timeout", f"episode exceeded {job.timeout_s:.0f} s; its Ray task was cancelled", now - t0)


def run_jobs(jobs: Iterable[Job], *, backend: str = "process", workers: int | None = None, address: str | None = None) -> Iterator[dict]:
    """Run jobs of any kind on a backend; yields each job's records as it finishes.

    Raises :class:`~conceptfusion.errors.HarnessError` (a ``ValueError``) for an unknown
    ``backend``, naming the nearest one.
    """
    jobs = list(jobs)
    if backend not in BACKENDS:
        raise HarnessError(f"backend: expected one of {BACKENDS}, got {backend!r}" + did_you_mean(backend, BACKENDS, n=1, cutoff=0.6))
    if not jobs:
        return iter(())
    workers = int(workers or os.cpu_count() or 1)
    if backend == "serial":
        return _serial(jobs)
    if backend == "ray":
        return _ray(jobs, workers, address)
    return _process_pool(jobs, workers)
