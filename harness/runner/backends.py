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
* ``process`` (default): ``workers`` processes (default: the CPU count), forked from a fork
  server (``forkserver``; ``spawn`` where the platform has none): a fresh interpreter started
  once per parent process that imports the heavy modules once (:mod:`harness.runner._preload`:
  torch, the text tower's libraries, MuJoCo, the job modules) and nothing of the parent's
  state, so no simulator or GL state is inherited and a worker starts warm instead of spending
  about 5 s of CPU on imports. Each worker takes the parent's environment variables as they are
  when it starts, as a spawned one would. A job that runs past its
  ``timeout_s`` has its worker killed and is recorded as ``timeout``; a worker that dies (a crash
  in native code, ``os._exit``) is recorded as ``failed`` with its exit code
  (``job.failure_record``). Both are replaced and the run goes on. Each worker gets its share of
  the cores (:func:`~harness.runner.jobs.worker_thread_share`, used by the map jobs). Workers die
  with the process that started them, even when it is killed with ``SIGKILL``: the fork server
  exits when its parent does, and a worker dies with the process it was forked from (Linux: a
  parent-death signal; elsewhere a thread that watches it) and when the process that started the
  pool is gone; with them goes the multiprocessing resource tracker, which exits once no process
  holds its pipe;
* ``ray``: ``ray.remote`` tasks on a cluster (``address="auto"``, ``"HOST:PORT"`` or
  ``"ray://host:10001"``) or a local Ray instance (``address=None``); timeouts cancel the task.
  Needs the ``ray`` extra. :func:`check_backend` probes the cluster with a bounded TCP connect
  and gives ``ray.init`` a bounded time before any job is sent.
"""

from __future__ import annotations

import ctypes
import logging
import multiprocessing as mp
import os
import queue
import signal
import socket
import sys
import threading
import time
from typing import Iterable, Iterator

from conceptfusion.errors import ConceptFusionError, HarnessError
from conceptfusion.names import did_you_mean
from harness.runner.jobs import WORKER_THREADS_ENV, Job, JobTimeout

__all__ = ["BACKENDS", "run_jobs", "one_blas_thread", "check_backend", "parse_ray_address", "RayUnavailableError", "expected_seconds", "longest_first"]

BACKENDS = ("process", "serial", "ray")

_log = logging.getLogger(__name__)

_PR_SET_PDEATHSIG = 1
"""``prctl`` option (``<linux/prctl.h>``): the signal a process gets when its parent dies."""

_PRELOAD = ("harness.runner._preload",)
"""What the fork server imports before it forks any worker."""


class RayUnavailableError(ConceptFusionError, RuntimeError):
    """Ray is not installed or its cluster cannot be reached (a ``RuntimeError``, not a ``ValueError``:
    a run that cannot start on Ray is not a bad setting; ``cfharness run`` still reports it with
    exit status 2)."""


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


def _run_job(job: Job) -> list[dict]:
    """What a worker runs for a job (module level, so that Ray ships it by reference); a
    ``SystemExit`` inside the job becomes its ``failed`` record. numpy's BLAS runs on one thread
    during the job (:func:`one_blas_thread`; restored afterwards, for the serial backend's
    caller)."""
    t0 = time.monotonic()
    try:
        with one_blas_thread():
            return job.run()
    except SystemExit as exc:
        return [job.failure_record("failed", f"SystemExit: the job called sys.exit({exc.code!r}); recorded as failed",
                                   time.monotonic() - t0)]


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
            return _run_job(job)
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
        records = _run_with_alarm(job) if timed else _run_job(job)
        yield from records  # the alarm is off while the caller handles the records


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's process: it exists
        return True
    return True


def _orphaned(direct_pid: int, parent_pid: int) -> bool:
    return os.getppid() != direct_pid or not _alive(parent_pid)


def _watch_parent(direct_pid: int, parent_pid: int) -> None:
    while True:
        time.sleep(0.5)
        if _orphaned(direct_pid, parent_pid):
            os._exit(1)


def _die_with_parent(parent_pid: int) -> None:
    """Make this worker process exit when ``parent_pid`` (the process that started the pool)
    dies, even by ``SIGKILL``. The process it was forked from (``parent_pid`` itself when spawned,
    else the fork server, which exits with ``parent_pid``) gets a ``prctl(PR_SET_PDEATHSIG,
    SIGKILL)`` on Linux, else a daemon thread that polls both. A parent that died before the
    signal was armed is caught too."""
    direct_pid = os.getppid()
    armed = False
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            armed = libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0) == 0
        except (OSError, AttributeError):  # no libc with prctl
            armed = False
    if direct_pid == 1 or _orphaned(direct_pid, parent_pid):  # orphaned already
        os._exit(1)
    if not armed or direct_pid != parent_pid:
        threading.Thread(target=_watch_parent, args=(direct_pid, parent_pid), name="cf-watch-parent", daemon=True).start()


def one_blas_thread():
    """A context in which the BLAS libraries loaded so far (numpy's and scipy's) run on one
    thread, restored on exit; every job runs in one (:func:`_run_job`). It looks the libraries
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


def _worker_main(inbox, outbox, threads: int, parent_pid: int, environ: dict[str, str]) -> None:
    """Worker loop: run jobs until told to stop (``None``); ``threads`` is the worker's share of
    the cores, for the jobs that limit their threads to it; ``environ`` the parent's environment
    variables when it started the worker. The worker dies with ``parent_pid``."""
    _die_with_parent(parent_pid)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent handles Ctrl-C
    os.environ.clear()
    os.environ.update(environ)
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
        self.proc = ctx.Process(target=_worker_main, args=(self.inbox, outbox, threads, os.getpid(), dict(os.environ)),
                                daemon=True)
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


def _pool_context():
    """The multiprocessing context of the process backend: a fork server that has imported
    :data:`_PRELOAD` (set before the server starts; a server already running keeps its own),
    else ``spawn``."""
    if "forkserver" not in mp.get_all_start_methods():
        return mp.get_context("spawn")
    ctx = mp.get_context("forkserver")
    ctx.set_forkserver_preload(list(_PRELOAD))
    return ctx


def _process_pool(jobs: list[Job], workers: int) -> Iterator[dict]:
    ctx = _pool_context()
    outbox = ctx.Queue()
    pending = [(i, jobs[i]) for i in longest_first(jobs)][::-1]
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

    remote = ray.remote(num_cpus=1, max_retries=0)(_run_job)
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
    return _process_pool(jobs, workers)
