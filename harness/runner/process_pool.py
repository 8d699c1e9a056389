"""The ``process`` backend: a local pool of worker processes (see :mod:`harness.runner.backends`).

Workers are forked from a fork server (``forkserver``; ``spawn`` where the platform has none): a
fresh interpreter, started once per parent process, that imports the heavy modules once
(:mod:`harness.runner._preload`: torch, the text tower's libraries, MuJoCo, the job modules) and
nothing of the parent's state, so no simulator or GL state is inherited and a worker starts warm
instead of spending about 5 s of CPU on imports. Each worker takes the parent's environment
variables as they are when it starts, as a spawned one would, and its share of the cores
(:data:`~harness.runner.jobs.WORKER_THREADS_ENV`, used by the map jobs).

A job that runs past its ``timeout_s`` has its worker killed and is recorded as ``timeout``; a
worker that dies (a crash in native code, ``os._exit``) is recorded as ``failed`` with its exit
code (``job.failure_record``). Both are replaced and the run goes on. Workers die with the
process that started the pool, even when it is killed with ``SIGKILL``: the fork server exits
when its parent does, and a worker dies with the process it was forked from (Linux: a
parent-death signal; elsewhere a thread that watches it) and when the pool's parent is gone;
with them goes the multiprocessing resource tracker, which exits once no process holds its pipe.
"""

from __future__ import annotations

import ctypes
import multiprocessing as mp
import os
import queue
import signal
import sys
import threading
import time
from typing import Iterator

from harness.runner.jobs import WORKER_THREADS_ENV, Job, longest_first, run_job

__all__ = ["process_pool"]

_PR_SET_PDEATHSIG = 1
"""``prctl`` option (``<linux/prctl.h>``): the signal a process gets when its parent dies."""

_PRELOAD = ("harness.runner._preload",)
"""What the fork server imports before it forks any worker."""


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
        outbox.put((index, run_job(job)))


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


def process_pool(jobs: list[Job], workers: int) -> Iterator[dict]:
    """Run ``jobs`` on ``workers`` local worker processes (see the module docstring), longest
    first (:func:`~harness.runner.jobs.longest_first`); yields each job's records as it
    finishes, a ``timeout`` record for a job past its ``timeout_s`` (its worker is killed and
    replaced) and a ``failed`` one for a job whose worker died."""
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
