"""The ``process`` backend: a local pool of worker processes (see :mod:`harness.runner.backends`).

Workers are forked from a fork server (``forkserver``; ``spawn`` where the platform has none): a
fresh interpreter, started once per parent process, that imports the heavy modules once
(:mod:`harness.runner._preload`: torch, the text tower's libraries, MuJoCo, the job modules) and
nothing of the parent's state, so no simulator or GL state is inherited and a worker starts warm
instead of spending about 5 s of CPU on imports. Each worker takes the parent's environment
variables as they are when it starts, as a spawned one would, and its share of the cores
(:data:`~harness.runner.jobs.WORKER_THREADS_ENV`, used by the map jobs).

A job that runs past its ``timeout_s`` has its worker killed (``SIGKILL``, which nothing in the
job can catch) and is recorded as ``timeout``; a worker that dies (a crash in native code,
``os._exit``) is recorded as ``failed`` with its exit code (``job.failure_record``). Both are
replaced and the run goes on. Workers die with the process that started the pool, even when it
is killed with ``SIGKILL``: the fork server exits when its parent does, and a worker dies with
the process it was forked from (Linux: a parent-death signal; elsewhere a thread that watches it)
and when the pool's parent is gone; with them goes the multiprocessing resource tracker, which
exits once no process holds its pipe.

**An agent's processes end with its episode** (Linux). Each worker leads its own session and is
the reaper of the orphans below it (``PR_SET_CHILD_SUBREAPER``), so whatever an agent starts
stays findable: below the worker, or at least in its session. When a job ends (its records came,
it timed out, its worker died or was stopped) the pool kills, with ``SIGKILL``, every process
below the worker and every other process of its session (:mod:`harness.runner.process_tree`);
the worker reaps them before its next job. Only a process that starts a session of its own and
whose parent then exits (a daemon made on purpose) escapes, and so do the agent's processes
when the run itself is killed with ``SIGKILL`` (the worker dies at once, with nobody left to
end them).

**Memory limit** (``memory_limit_mb``; None: none). The pool reads each busy worker's memory
every 0.1 s: what it has allocated beyond what it held when it started
(:func:`~harness.runner.process_tree.allocated_mib`: anonymous and shared-memory pages, swapped
ones included; not the files it maps). A worker past the limit is killed and its job recorded
``failed`` with "memory limit of N MiB exceeded", and so is a job whose worker is past it when
the job returns. A worker holding more than half the limit when its job ends (what an agent
leaked, caches) is replaced before its next job, so a leak cannot grow a reused worker without
bound and every episode starts with at least half the limit free.

Why a parent watching ``/proc`` and not ``RLIMIT_AS`` in the worker: the address-space limit
counts virtual memory, which the preloaded libraries reserve far beyond what they use (torch,
EGL and the GL drivers map large regions; CUDA reserves terabytes), so a limit that means
anything for the episode would stop the worker before it ran; and past it an allocation fails
with a ``MemoryError`` the agent can catch, or in a native library that crashes on it. Why
growth over the start: a worker is forked from the fork server and starts with about 360 MiB
of its heap resident (the preloaded libraries' objects, shared with the server until written);
charging every episode for them would make a limit of a few hundred MiB meaningless. (The
private set size of ``/proc/PID/smaps_rollup`` would count those pages as soon as Python's
garbage collector writes to them, and costs milliseconds per reading.) The price of watching
from outside is that it samples: a worker can go past the limit by what it allocates in one
0.1 s interval before it is stopped, and a spike that comes and goes between two readings is
not seen.
"""

from __future__ import annotations

import ctypes
import logging
import multiprocessing as mp
import os
import signal
import sys
import threading
import time
from multiprocessing.connection import wait
from typing import Iterator

from harness.runner import process_tree
from harness.runner.jobs import WORKER_THREADS_ENV, Job, longest_first, run_job

__all__ = ["process_pool"]

_log = logging.getLogger(__name__)

_PR_SET_PDEATHSIG = 1
"""``prctl`` option (``<linux/prctl.h>``): the signal a process gets when its parent dies."""

_PRELOAD = ("harness.runner._preload",)
"""What the fork server imports before it forks any worker."""

_POLL_S = 0.5
"""How often the pool looks at its workers (timeouts, deaths) without a memory limit."""

_MEMORY_POLL_S = 0.1
"""How often it looks with a memory limit: each busy worker's memory is read each time."""

_RECYCLE_FRACTION = 0.5
"""A worker holding more than this fraction of the memory limit when its job ends is replaced."""


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
    dies, even by ``SIGKILL``. On Linux the worker arms ``prctl(PR_SET_PDEATHSIG, SIGKILL)`` for
    the death of the process it was forked from (``parent_pid`` itself when spawned, else the fork
    server, which exits with ``parent_pid``); where the two differ, or the signal cannot be armed,
    a daemon thread polls both. A parent that died before the signal was armed is caught too."""
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


def _worker_main(inbox, results, threads: int, parent_pid: int, environ: dict[str, str]) -> None:
    """Worker loop: run jobs from ``inbox`` until told to stop (``None``), sending each one's
    records down ``results`` (its own pipe); ``threads`` is the worker's share of
    the cores, for the jobs that limit their threads to it; ``environ`` the parent's environment
    variables when it started the worker. The worker dies with ``parent_pid``, leads a session
    of its own and adopts the orphans below it (the processes its jobs start stay findable), and
    reaps before each job what the pool ended of the last one."""
    _die_with_parent(parent_pid)
    try:
        os.setsid()
    except OSError:  # already a session or group leader: the processes below it are still found
        pass
    process_tree.become_child_subreaper()
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent handles Ctrl-C
    os.environ.clear()
    os.environ.update(environ)
    os.environ[WORKER_THREADS_ENV] = str(threads)
    while True:
        item = inbox.get()
        process_tree.reap_children()
        if item is None:
            break
        index, job = item
        results.send((index, run_job(job)))


class _Worker:
    """One worker process, its inbox of jobs and its own pipe of results: a pipe, not a queue
    shared by the workers, because a worker killed while it held a shared queue's write lock
    (``SIGKILL`` a moment after it sent a result, before it let go of the lock) would leave
    every other worker unable to answer."""

    def __init__(self, ctx, threads: int) -> None:
        self.inbox = ctx.Queue()
        self.results, sender = ctx.Pipe(duplex=False)
        self.proc = ctx.Process(target=_worker_main, args=(self.inbox, sender, threads, os.getpid(), dict(os.environ)),
                                daemon=True)
        self.proc.start()
        sender.close()  # the worker holds the only sending end: its death reads as the end of the pipe
        self.job: tuple[int, Job] | None = None
        self.started = 0.0
        self.start_mib: float | None = None  # what it held when given its first job (process_tree.allocated_mib)

    def assign(self, index: int, job: Job) -> None:
        if self.start_mib is None:
            self.start_mib = process_tree.allocated_mib(self.proc.pid)
        self.job, self.started = (index, job), time.monotonic()
        self.inbox.put((index, job))

    def end_processes(self, label: str) -> None:
        """Kill every process the worker's job ``label`` started (below it or in its session)."""
        ended = process_tree.end_processes(process_tree.descendants(self.proc.pid, session=True))
        if ended:
            _log.warning("%s: ended %d process(es) it left running: %s", label, len(ended), ended)

    def memory_mib(self) -> float | None:
        """MiB the worker allocated since it started (None when that cannot be read)."""
        now = process_tree.allocated_mib(self.proc.pid)
        if now is None or self.start_mib is None:
            return None
        return max(0.0, now - self.start_mib)

    def kill(self, label: str | None = None) -> None:
        """Stop the worker and every process its jobs started, those orphaned by its death too
        (logged as left running by job ``label``, when given)."""
        below = set(process_tree.descendants(self.proc.pid, session=True))
        if self.proc.is_alive():
            self.proc.kill()
        self.proc.join(timeout=5)
        self.results.close()
        ended = process_tree.end_processes(below | set(process_tree.session_members(self.proc.pid)))
        if ended and label:
            _log.warning("%s: ended %d process(es) it left running: %s", label, len(ended), ended)


def _pool_context():
    """The multiprocessing context of the process backend: a fork server that has imported
    :data:`_PRELOAD` (set before the server starts; a server already running keeps its own),
    else ``spawn``."""
    if "forkserver" not in mp.get_all_start_methods():
        return mp.get_context("spawn")
    ctx = mp.get_context("forkserver")
    ctx.set_forkserver_preload(list(_PRELOAD))
    return ctx


def _memory_error(limit_mib: int, held_mib: float, when: str) -> str:
    return (f"memory limit of {limit_mib} MiB exceeded: its worker held {held_mib:.0f} MiB more than when it started, "
            f"{when}; the worker was stopped")


def process_pool(jobs: list[Job], workers: int, *, memory_limit_mb: int | None = None) -> Iterator[dict]:
    """Run ``jobs`` on ``workers`` local worker processes (see the module docstring), longest
    first (:func:`~harness.runner.jobs.longest_first`); yields each job's records as it
    finishes, a ``timeout`` record for a job past its ``timeout_s`` (its worker is killed and
    replaced), a ``failed`` one for a job whose worker died and, with ``memory_limit_mb``, a
    ``failed`` one ("memory limit of N MiB exceeded") for a job whose worker went past that many
    MiB beyond what it started with. The processes a job started are killed when it ends. One
    record set per job: a worker stopped as it answered is recorded once, by its stop."""
    ctx = _pool_context()
    pending = [(i, jobs[i]) for i in longest_first(jobs)][::-1]
    size = max(1, min(workers, len(jobs)))
    threads = max(1, (os.cpu_count() or 1) // size)
    pool = [_Worker(ctx, threads) for _ in range(size)]
    poll = _POLL_S if memory_limit_mb is None else _MEMORY_POLL_S
    done = 0
    try:
        while done < len(jobs):
            for w in pool:
                if w.job is None and pending:
                    w.assign(*pending.pop())
            busy = {w.results: k for k, w in enumerate(pool) if w.job is not None}
            for conn in wait(list(busy), timeout=poll):
                k = busy[conn]
                try:
                    index, records = conn.recv()
                except (EOFError, OSError):  # the worker died: recorded below
                    continue
                if pool[k].job is not None and pool[k].job[0] == index:
                    w, job = pool[k], pool[k].job[1]
                    elapsed, w.job = time.monotonic() - w.started, None
                    w.end_processes(job.label)
                    held = w.memory_mib() if memory_limit_mb is not None else None
                    if held is not None and held > memory_limit_mb:
                        records = [job.failure_record("failed", _memory_error(memory_limit_mb, held, "when the episode ended"),
                                                      elapsed)]
                    if held is not None and held > _RECYCLE_FRACTION * memory_limit_mb:
                        w.kill()
                        pool[k] = _Worker(ctx, threads)
                    done += 1
                    yield from records
            now = time.monotonic()
            for k, w in enumerate(pool):
                if w.job is None:
                    continue
                index, job = w.job
                elapsed = now - w.started
                if elapsed > job.timeout_s:
                    w.kill(job.label)
                    pool[k] = _Worker(ctx, threads)
                    done += 1
                    yield job.failure_record("timeout", f"episode exceeded {job.timeout_s:g} s; its worker was stopped", elapsed)
                elif not w.proc.is_alive():
                    code = w.proc.exitcode
                    w.kill(job.label)  # ends what its job started
                    pool[k] = _Worker(ctx, threads)
                    done += 1
                    yield job.failure_record("failed", f"worker process died (exit code {code}) during the episode", elapsed)
                elif memory_limit_mb is not None:
                    held = w.memory_mib()
                    if held is not None and held > memory_limit_mb:
                        w.kill(job.label)
                        pool[k] = _Worker(ctx, threads)
                        done += 1
                        yield job.failure_record("failed", _memory_error(memory_limit_mb, held, "during the episode"), elapsed)
    finally:
        for w in pool:
            if w.proc.is_alive():
                w.inbox.put(None)
        for w in pool:
            w.proc.join(timeout=2)
            w.kill()
