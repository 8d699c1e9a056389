"""Where jobs run: in this process, in a local pool of worker processes, or on a Ray cluster.

Every backend takes :class:`~harness.runner.jobs.Job` s (episode jobs and map jobs alike), calls
``job.run()`` and yields the result records as jobs finish (in completion order; records carry
their keys). Results do not depend on the backend: a job is a pure function of its fields
(scene, episode, seed, agent settings). A ``SystemExit`` raised inside a job is recorded as
``failed`` on every backend.

The pool backends (``process`` and ``ray``) start the longest jobs first (a job's optional
``expected_s``, rough seconds; 1 when it has none; ties keep the given order): with every suite's
jobs in one pool, short jobs fill the gaps at the end instead of one long search episode
running alone while the other workers idle (longest-processing-time-first scheduling; its
makespan is within 4/3 of the best possible).

* ``serial``: one job after another in this process (debugging, tests). A job past its
  ``timeout_s`` is interrupted by ``SIGALRM`` (:class:`~harness.runner.jobs.JobTimeout`, raised
  again every second should the job swallow it) and recorded as ``timeout``; this needs the main
  thread of a POSIX process (elsewhere there is no timeout, and a warning says so), and a long
  native call (rendering, a torch op) finishes before the handler runs. ``os._exit`` or a crash
  in native code cannot be caught in-process: they end the run without a record of that job
  (``--resume`` runs it again); use the process backend for agents that may do that;
* ``process`` (default): ``workers`` processes (default: the CPU count) forked from a fork
  server that has imported the heavy modules once (:mod:`harness.runner.process_pool`). A job
  that runs past its ``timeout_s`` has its worker killed and is recorded as ``timeout``; a
  worker that dies (a crash in native code, ``os._exit``) is recorded as ``failed`` with its
  exit code. Both are replaced and the run goes on. Workers die with the process that started
  them, even when it is killed with ``SIGKILL``;
* ``ray``: ``ray.remote`` tasks on a cluster (``address="auto"``, ``"HOST:PORT"`` or
  ``"ray://host:10001"``) or a local Ray instance (``address=None``); timeouts cancel the task.
  Needs the ``ray`` extra. :func:`check_backend` probes the cluster with a bounded TCP connect
  and gives ``ray.init`` a bounded time before any job is sent.
"""

from __future__ import annotations

import logging
import os
import signal
import socket
import threading
import time
from typing import Iterable, Iterator

from conceptfusion.errors import ConceptFusionError, HarnessError
from conceptfusion.names import did_you_mean
from harness.runner.jobs import Job, JobTimeout, longest_first, run_job
from harness.runner.process_pool import process_pool

__all__ = ["BACKENDS", "run_jobs", "check_backend", "parse_ray_address", "RayUnavailableError"]

BACKENDS = ("process", "serial", "ray")

_log = logging.getLogger(__name__)

class RayUnavailableError(ConceptFusionError, RuntimeError):
    """Ray is not installed or its cluster cannot be reached (a ``RuntimeError``, not a ``ValueError``:
    a run that cannot start on Ray is not a bad setting; ``cfharness run`` still reports it with
    exit status 2)."""


_MAX_ALARM_S = 1e8
"""Longest ``SIGALRM`` delay set (about three years; ``setitimer`` overflows far beyond)."""


def _serial_timeouts() -> bool:
    return hasattr(signal, "setitimer") and threading.current_thread() is threading.main_thread()


def _run_with_alarm(job: Job) -> list[dict]:
    """Run ``job`` here with ``SIGALRM`` at its ``timeout_s`` (and every second after, should the
    job swallow the :class:`JobTimeout`); its records, or its ``timeout`` record."""
    def on_alarm(signum, frame):
        signal.setitimer(signal.ITIMER_REAL, 1.0)
        raise JobTimeout(f"{job.label}: past {job.timeout_s:g} s")

    previous = signal.signal(signal.SIGALRM, on_alarm)
    t0 = time.monotonic()
    try:
        try:
            signal.setitimer(signal.ITIMER_REAL, min(float(job.timeout_s), _MAX_ALARM_S))
            return run_job(job)
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
    except JobTimeout:
        return [job.failure_record("timeout", f"episode exceeded {job.timeout_s:g} s; interrupted by SIGALRM on the serial "
                                   "backend", time.monotonic() - t0)]
    finally:
        signal.signal(signal.SIGALRM, previous)


def _serial(jobs: list[Job]) -> Iterator[dict]:
    timed = _serial_timeouts()
    if not timed:
        _log.warning("serial backend outside the main thread (or without SIGALRM): jobs run without their timeout")
    for job in jobs:
        records = _run_with_alarm(job) if timed else run_job(job)
        yield from records  # the alarm is off while the caller handles the records


def parse_ray_address(address: str | None) -> tuple[str, int] | None:
    """``(host, port)`` of a Ray address to probe: ``"HOST:PORT"`` (the cluster's GCS, default
    port 6379) or ``"ray://HOST[:PORT]"`` (Ray Client, default 10001); None for ``None``,
    ``"auto"`` and ``"local"`` (Ray finds or starts the instance itself).

    Raises:
        HarnessError: an address of another form (a ``ValueError``).
    """
    if address is None or address.strip() in ("auto", "local"):
        return None
    text, default = address.strip(), 6379
    if text.startswith("ray://"):
        text, default = text[len("ray://"):], 10001
    host, sep, port = text.rpartition(":")
    if not sep:
        host, port = text, str(default)
    host = host.strip("[]")
    if not host or "/" in host or not port.isdigit() or not 0 < int(port) < 65536:
        raise HarnessError(f"--address: expected 'auto', 'HOST:PORT' or 'ray://HOST:PORT', got {address!r}")
    return host, int(port)


def _ray_init(address: str | None, workers: int, timeout_s: float) -> None:
    """``ray.init`` with a bounded wait: connecting to a cluster runs in a daemon thread that
    stays alive afterwards (Ray ties processes it starts to the starting thread)."""
    import ray

    if not address:  # a new local instance: nothing remote to wait for
        ray.init(num_cpus=max(1, workers), ignore_reinit_error=True, log_to_driver=False, include_dashboard=False)
        return
    outcome: dict = {}
    ready = threading.Event()

    def connect() -> None:
        try:
            ray.init(address=address, ignore_reinit_error=True, log_to_driver=False)
        except BaseException as exc:  # reported to the caller
            outcome["error"] = exc
        ready.set()
        threading.Event().wait()  # keep the thread (and what Ray tied to it) alive

    threading.Thread(target=connect, name="cf-ray-init", daemon=True).start()
    if not ready.wait(timeout_s):
        raise RayUnavailableError(f"--address {address}: the Ray cluster did not answer within {timeout_s:g} s")
    if "error" in outcome:
        raise outcome["error"]


def check_backend(backend: str, address: str | None = None, *, workers: int | None = None,
                  connect_timeout_s: float = 5.0, init_timeout_s: float = 120.0) -> None:
    """Make sure ``backend`` can run jobs before any is sent; the Ray backend is connected here
    (:func:`run_jobs` then reuses the connection).

    For ``ray`` with an address: a TCP connect to it bounded by ``connect_timeout_s``, then
    ``ray.init`` bounded by ``init_timeout_s``. ``process`` and ``serial`` need nothing.

    Raises:
        HarnessError: unknown backend (naming the nearest) or a malformed address.
        RayUnavailableError: Ray is not installed, or the cluster does not answer in time.
    """
    if backend not in BACKENDS:
        raise HarnessError(f"backend: expected one of {BACKENDS}, got {backend!r}" + did_you_mean(backend, BACKENDS, n=1, cutoff=0.6))
    if backend != "ray":
        return
    target = parse_ray_address(address)
    try:
        import ray
    except ImportError as exc:
        raise RayUnavailableError('the ray backend needs Ray: pip install -e ".[ray]"') from exc
    if ray.is_initialized():
        return
    if target is not None:
        try:
            socket.create_connection(target, timeout=connect_timeout_s).close()
        except OSError as exc:
            raise RayUnavailableError(f"--address {address}: cannot reach a Ray cluster at {target[0]}:{target[1]} "
                                      f"within {connect_timeout_s:g} s ({exc})") from exc
    try:
        _ray_init(address, int(workers or os.cpu_count() or 1), init_timeout_s)
    except RayUnavailableError:
        raise
    except Exception as exc:  # ConnectionError, RuntimeError ... depending on the Ray version
        raise RayUnavailableError(f"cannot reach the Ray cluster at {address or 'a new local instance'}: {exc}") from exc


def _ray(jobs: list[Job], workers: int, address: str | None) -> Iterator[dict]:
    check_backend("ray", address, workers=workers)
    import ray

    remote = ray.remote(num_cpus=1, max_retries=0)(run_job)
    refs = {remote.remote(jobs[i]): (jobs[i], time.monotonic()) for i in longest_first(jobs)}
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
    ``backend``, naming the nearest one, and :class:`RayUnavailableError` (when the records are
    first asked for) for a Ray backend that cannot be reached.
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
    return process_pool(jobs, workers)
