"""The one job model: what a backend runs, whatever the suite.

A :class:`Job` is a picklable, self-contained unit of work (one episode of an agent, one map
scene of a map suite) that knows its record key, how long it may take, and how to run itself
into result records (see :mod:`harness.runner.results`). The backends
(:mod:`harness.runner.backends`) only call :meth:`Job.run` and, when a worker times out or
dies, :meth:`Job.failure_record`; they never look at what kind of job it is.

Implemented by :class:`harness.runner.tasks.EpisodeJob` and :class:`harness.runner.map_jobs.MapJob`.
This module imports nothing of the harness but :mod:`harness.runner.results`.
"""

from __future__ import annotations

import contextlib
import os
import threading
import time
from typing import Iterable, Iterator, Protocol, runtime_checkable

from conceptfusion.perception.encoders import THREADS_ENV
from harness.runner.results import make_record

__all__ = ["Job", "JobTimeout", "job_deadline", "check_deadline", "note_interrupt", "job_record", "import_plugins",
           "WORKER_THREADS_ENV", "worker_thread_share", "run_job", "one_blas_thread", "expected_seconds", "longest_first"]

WORKER_THREADS_ENV = THREADS_ENV
"""Set by the process backend in each worker: that worker's share of the CPU cores (encoders
size their onnxruntime thread pools by it)."""


class JobTimeout(BaseException):
    """Raised inside a job that runs past its ``timeout_s`` on the serial backend: from a
    ``SIGALRM`` handler, and by :func:`check_deadline` when the agent's code returns past the
    deadline. A ``BaseException``, like ``KeyboardInterrupt``: a job's ``except Exception`` does
    not turn it into a ``failed`` record; the backend records ``timeout`` with the exception's
    text, which says how the job was stopped. Jobs clean up (close environments) and let it
    through."""


class _Deadline(threading.local):
    """Per thread: when its in-process job must end (None: no deadline) and how many timeout
    interrupts were raised into it."""

    at: float | None = None
    interrupts: int = 0


_DEADLINE = _Deadline()
"""The deadline of the job this thread runs in-process (serial backend), or None."""


@contextlib.contextmanager
def job_deadline(timeout_s: float) -> Iterator[None]:
    """Run the block (one job, in this thread) with a deadline ``timeout_s`` seconds from now,
    which :func:`check_deadline` enforces. The serial backend sets it; in a pool worker there is
    none (the pool kills the worker instead)."""
    _DEADLINE.at, _DEADLINE.interrupts = time.monotonic() + float(timeout_s), 0
    try:
        yield
    finally:
        _DEADLINE.at = None


def note_interrupt() -> int:
    """Count one timeout interrupt (``SIGALRM``) raised into the running job; the count so far."""
    _DEADLINE.interrupts += 1
    return _DEADLINE.interrupts


def check_deadline(event: str) -> None:
    """Raise :class:`JobTimeout` when this thread's job (:func:`job_deadline`) is past its
    deadline; nothing without one. Called by the episode runner each time the agent's code
    returns to it (``event`` says what happened: ``"agent.act returned"``), so that an agent
    which catches the timeout interrupt (a bare ``except``) is still stopped at its next
    return: this raise happens in the harness's code, out of the agent's reach."""
    at = _DEADLINE.at
    if at is None or time.monotonic() <= at:
        return
    n = _DEADLINE.interrupts
    caught = f"the job caught the SIGALRM interrupt {'once' if n == 1 else f'{n} times'}; " if n else ""
    raise JobTimeout(f"{caught}stopped on the serial backend when {event}, past its deadline")


@runtime_checkable
class Job(Protocol):
    """One unit of work for a backend: picklable, deterministic, independent of other jobs."""

    run_id: str
    suite: str
    timeout_s: float
    """Wall-clock limit; past it the backends stop the job and record ``timeout`` (the serial
    backend raises :class:`JobTimeout` in it)."""
    plugins: tuple[str, ...]
    """Modules the job imports in its worker before it runs (they register user agents)."""

    @property
    def task(self) -> str:
        """The ``task`` field of the job's records."""

    @property
    def label(self) -> str:
        """A short human-readable name (progress lines, logs)."""

    def key_record(self) -> dict:
        """The key fields of the job's record (``suite, agent, agent_kwargs, encoder, episode_id,
        seed``), as :func:`harness.runner.results.record_key` reads them; resume skips a job whose
        key is already stored."""

    def run(self) -> list[dict]:
        """Run the job; its result records. Never raises for what goes wrong inside the job:
        that becomes a record with ``status="failed"`` and the error (a ``SystemExit`` too).
        Lets :class:`JobTimeout` and ``KeyboardInterrupt`` through."""

    def failure_record(self, status: str, error: str, wall_s: float) -> dict:
        """The record of the job when its worker timed out (``status="timeout"``) or died
        (``"failed"``) before it returned."""


def job_record(job: Job, *, status: str, error: str | None = None, metrics: dict | None = None,
               timings: dict | None = None, category: str | None = None, extras: dict | None = None) -> dict:
    """A validated results record for ``job``: its key fields, ``run_id`` and ``task``, plus the
    given outcome (see :func:`harness.runner.results.make_record`)."""
    return make_record(
        run_id=job.run_id, task=job.task, **job.key_record(), status=status, error=error, metrics=metrics or {},
        timings=timings or {}, category=category, extras=extras or {},
    )


def import_plugins(plugins: Iterable[str] | None) -> None:
    """Import the modules that register user agents.

    Raises:
        ValueError: naming the module that fails and how: it cannot be found or imported
            (``ImportError``), its code raised (the exception's type and message), or it called
            ``sys.exit`` while being imported (refused, instead of ending the caller with its
            exit code).
    """
    from agents.spec import import_module_cleanly

    for name in plugins or ():
        import_module_cleanly(name, f"--import {name!r}", "a module that imports cleanly (it registers agents or encoders)")


@contextlib.contextmanager
def worker_thread_share() -> Iterator[None]:
    """Run the block with torch's intra-op threads limited to this worker's share of the cores
    (:data:`WORKER_THREADS_ENV`, set by the process backend), then restore them.

    Without it, every worker of a pool runs torch on all cores and they fight over them. Only jobs
    whose results do not depend on torch's thread count use it: the map suites' records are the
    same with one thread or many, while a search episode's path can move in its last digits
    (text embeddings differ in their last bits), so episode jobs keep torch's default.
    """
    share = os.environ.get(WORKER_THREADS_ENV)
    try:
        import torch
    except ImportError:  # no torch, nothing to share
        torch = None
    if not share or torch is None:
        yield
        return
    before = torch.get_num_threads()
    torch.set_num_threads(max(1, int(share)))
    try:
        yield
    finally:
        torch.set_num_threads(before)


def one_blas_thread():
    """A context in which the BLAS libraries loaded so far (numpy's and scipy's) run on one
    thread, restored on exit; every job runs in one (:func:`run_job`). It looks the libraries
    up afresh each time, so those an earlier job loaded count too (the map's own
    :func:`conceptfusion.map._threads.one_blas_thread` keeps the set it found first, for the
    per-frame cost).

    numpy's OpenBLAS otherwise keeps a thread per core that spins after each matrix product,
    burning the CPU the next render or proposal pass needs: in a worker of a full pool (one core
    each), a search step took 78 ms of CPU with it and 46 ms without, for the same wall time.
    Alone on the machine one thread is faster too: the spinning threads hold the core
    onnxruntime's second thread wants (a v2 search step: 33-35 ms wall and 58-63 ms CPU with two
    BLAS threads, 29 ms and 34 ms with one). The results are the same (its products split rows,
    not sums, across threads).
    """
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=1, user_api="blas")


def run_job(job: Job) -> list[dict]:
    """Run ``job`` into its records, as every backend does (module level, so that Ray ships it by
    reference); a ``SystemExit`` inside the job becomes its ``failed`` record. numpy's BLAS runs
    on one thread during the job (:func:`one_blas_thread`; restored afterwards, for the serial
    backend's caller)."""
    t0 = time.monotonic()
    try:
        with one_blas_thread():
            return job.run()
    except SystemExit as exc:
        return [job.failure_record("failed", f"SystemExit: the job called sys.exit({exc.code!r}); recorded as failed",
                                   time.monotonic() - t0)]


def expected_seconds(job: Job) -> float:
    """A job's ``expected_s`` when it has a positive finite one, else 1."""
    value = getattr(job, "expected_s", None)
    try:
        value = float(value)
    except (TypeError, ValueError):
        return 1.0
    return value if 0 < value < float("inf") else 1.0


def longest_first(jobs: list[Job]) -> list[int]:
    """Indices of ``jobs`` by :func:`expected_seconds`, longest first; ties keep their order."""
    return sorted(range(len(jobs)), key=lambda i: -expected_seconds(jobs[i]))
