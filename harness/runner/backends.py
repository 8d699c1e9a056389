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
  ``timeout_s`` is stopped two ways, and recorded as ``timeout``: ``SIGALRM`` interrupts it
  (:class:`~harness.runner.jobs.JobTimeout`, raised again every second should the job catch
  it), and the episode runner checks the clock each time the agent's code returns to it
  (constructor, ``reset``, ``act``; :func:`~harness.runner.jobs.check_deadline`), so an agent
  that catches every exception is stopped when its call returns, at most one call past the
  deadline. What the serial backend cannot stop: a call that never returns, because it catches
  the interrupt in a loop or sits in native code (a long render or torch op finishes before the
  handler runs; one that never finishes never lets it run). The run then waits on that call,
  with a warning logged once a second interrupt was needed, until the call returns or the run
  is killed (``--resume`` runs that episode again); use the process backend for such agents.
  The interrupt needs the main thread of a POSIX process; elsewhere only the clock check holds
  (a warning says so). ``os._exit`` or a crash in native code cannot be caught in-process:
  they end the run without a record of that job (``--resume`` runs it again). Processes the
  job started and left running are killed when it ends (:mod:`harness.runner.process_tree`;
  one whose parent exited, a double-forked daemon, is no longer below this process and
  escapes). ``memory_limit_mb`` is refused: stopping this process would end the run;
* ``process`` (default): ``workers`` processes (default: the CPU count) forked from a fork
  server that has imported the heavy modules once (:mod:`harness.runner.process_pool`). A job
  that runs past its ``timeout_s`` has its worker killed and is recorded as ``timeout``
  (nothing the agent catches can stop that); a worker that dies (a crash in native code,
  ``os._exit``) is recorded as ``failed`` with its exit code; with ``memory_limit_mb`` a
  worker found holding more than that many MiB beyond what it started with is killed and its
  job recorded ``failed`` ("memory limit of N MiB exceeded"). All are replaced and the run goes on. The processes an
  agent starts end with its episode, and workers die with the process that started them, even
  when it is killed with ``SIGKILL``;
* ``ray``: ``ray.remote`` tasks on a cluster (``address="auto"``, ``"HOST:PORT"`` or
  ``"ray://host:10001"``) or a local Ray instance (``address=None``); timeouts cancel the task
  (``force=True``: its worker process is killed). ``memory_limit_mb`` is refused (Ray has its
  own memory monitor). Needs the ``ray`` extra. :func:`check_backend` probes the cluster with a
  bounded TCP connect and gives ``ray.init`` a bounded time before any job is sent.
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
from harness.runner import process_tree
from harness.runner.jobs import Job, JobTimeout, job_deadline, longest_first, note_interrupt, run_job
from harness.runner.process_pool import process_pool

__all__ = ["BACKENDS", "run_jobs", "check_backend", "parse_ray_address", "RayUnavailableError", "memory_limit_refusal"]

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
    """Run ``job`` here with its deadline (:func:`~harness.runner.jobs.job_deadline`) and
    ``SIGALRM`` at its ``timeout_s`` (and every second after, should the job catch the
    :class:`JobTimeout`); its records, or its ``timeout`` record."""
    def on_alarm(signum, frame):
        signal.setitimer(signal.ITIMER_REAL, 1.0)
        if note_interrupt() == 2:
            _log.warning("%s: still running %.0f s past its %g s timeout: it caught the timeout interrupt; the serial "
                         "backend raises it again every second and stops the job when its call returns, but cannot "
                         "stop a call that never returns (use --backend process)", job.label,
                         time.monotonic() - t0 - job.timeout_s, job.timeout_s)
        raise JobTimeout("interrupted by SIGALRM on the serial backend")

    previous = signal.signal(signal.SIGALRM, on_alarm)
    t0 = time.monotonic()
    try:
        try:
            with job_deadline(job.timeout_s):
                signal.setitimer(signal.ITIMER_REAL, min(float(job.timeout_s), _MAX_ALARM_S))
                return run_job(job)
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
    except JobTimeout as exc:
        return [job.failure_record("timeout", f"episode exceeded {job.timeout_s:g} s; {exc}", time.monotonic() - t0)]
    finally:
        signal.signal(signal.SIGALRM, previous)


def _run_with_deadline(job: Job) -> list[dict]:
    """Run ``job`` here with its deadline only (no ``SIGALRM``: not the main thread)."""
    t0 = time.monotonic()
    try:
        with job_deadline(job.timeout_s):
            return run_job(job)
    except JobTimeout as exc:
        return [job.failure_record("timeout", f"episode exceeded {job.timeout_s:g} s; {exc}", time.monotonic() - t0)]


def _serial(jobs: list[Job]) -> Iterator[dict]:
    timed = _serial_timeouts()
    if not timed:
        _log.warning("serial backend outside the main thread (or without SIGALRM): a job past its timeout is stopped "
                     "only when the agent's call returns")
    me = os.getpid()
    for job in jobs:
        before = set(process_tree.descendants(me))
        try:
            records = _run_with_alarm(job) if timed else _run_with_deadline(job)
        finally:
            left = [pid for pid in process_tree.descendants(me) if pid not in before]
            if left:
                _log.warning("%s: ending %d process(es) it left running: %s", job.label, len(left), left)
                process_tree.end_processes(left)
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


def run_jobs(jobs: Iterable[Job], *, backend: str = "process", workers: int | None = None, address: str | None = None,
             memory_limit_mb: int | None = None) -> Iterator[dict]:
    """Run jobs of any kind on a backend; yields each job's records as it finishes.

    ``memory_limit_mb`` (process backend only; None: no limit) holds each job's worker to that
    many MiB of memory beyond what it started with (see :mod:`harness.runner.process_pool`).

    Raises :class:`~conceptfusion.errors.HarnessError` (a ``ValueError``) for an unknown
    ``backend``, naming the nearest one, or a memory limit on a backend other than ``process``,
    and :class:`RayUnavailableError` (when the records are first asked for) for a Ray backend
    that cannot be reached.
    """
    jobs = list(jobs)
    if backend not in BACKENDS:
        raise HarnessError(f"backend: expected one of {BACKENDS}, got {backend!r}" + did_you_mean(backend, BACKENDS, n=1, cutoff=0.6))
    refusal = memory_limit_refusal(backend) if memory_limit_mb is not None else None
    if refusal:
        raise HarnessError(refusal)
    if not jobs:
        return iter(())
    workers = int(workers or os.cpu_count() or 1)
    if backend == "serial":
        return _serial(jobs)
    if backend == "ray":
        return _ray(jobs, workers, address)
    return process_pool(jobs, workers, memory_limit_mb=memory_limit_mb)


def memory_limit_refusal(backend: str) -> str | None:
    """Why a memory limit cannot hold on ``backend`` here (anything but ``process``, or a
    machine whose ``/proc`` does not give processes' memory), None when it can."""
    if backend == "process":
        if process_tree.reads_memory():
            return None
        return ("--memory-limit-mb: needs the memory counters of /proc/PID/status (RssAnon: Linux 4.5 or later), "
                "got none on this machine")
    why = {"serial": "the serial backend runs episodes in this process, which it cannot stop without ending the run",
           "ray": "Ray tasks are held by Ray's own memory monitor"}.get(backend, "")
    return (f"--memory-limit-mb: only for --backend process (each episode's worker process is watched and stopped past "
            f"the limit), got --backend {backend}" + (f": {why}" if why else ""))
