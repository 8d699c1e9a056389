"""What an episode leaves behind in processes, read from ``/proc`` (Linux): the processes an
agent started, and how much memory a worker process has allocated.

The backends use it to end an agent's child processes with its episode
(:func:`descendants`, :func:`end_processes`) and, on the process backend, to hold each episode's
worker to a memory limit (:func:`allocated_mib`). Where ``/proc`` is missing (not Linux)
every function finds nothing: no processes, no memory reading.
"""

from __future__ import annotations

import ctypes
import logging
import os
import signal
import sys
import time
from pathlib import Path

__all__ = ["descendants", "session_members", "end_processes", "allocated_mib", "reads_memory",
           "become_child_subreaper", "reap_children"]

_log = logging.getLogger(__name__)

_PROC = Path("/proc")

_PR_SET_CHILD_SUBREAPER = 36
"""``prctl`` option (``<linux/prctl.h>``, Linux >= 3.4): orphans below this process are
re-parented to it instead of to init."""


def _process_table() -> dict[int, tuple[int, int]]:
    """pid -> (parent pid, session id) of every living process (zombies left out), from
    ``/proc/PID/stat``; empty without ``/proc``."""
    table: dict[int, tuple[int, int]] = {}
    try:
        entries = [p for p in _PROC.iterdir() if p.name.isdigit()]
    except OSError:
        return table
    for entry in entries:
        try:
            text = (entry / "stat").read_text()
        except OSError:  # gone meanwhile
            continue
        fields = text[text.rindex(")") + 2:].split()  # after "pid (comm) ": state ppid pgrp session ...
        if len(fields) < 4 or fields[0] in ("Z", "X"):
            continue
        table[int(entry.name)] = (int(fields[1]), int(fields[3]))
    return table


def descendants(pid: int, *, session: bool = False) -> list[int]:
    """The living processes below ``pid`` (its children, their children, ...), and with
    ``session`` also every other living process of the session ``pid`` leads (those whose parent
    died, a double-forked daemon among them, keep their session id unless they start their own).
    ``pid`` itself is never in the list."""
    table = _process_table()
    children: dict[int, list[int]] = {}
    for child, (parent, _) in table.items():
        children.setdefault(parent, []).append(child)
    found: set[int] = set()
    todo = [pid]
    while todo:
        for child in children.get(todo.pop(), ()):
            if child not in found:
                found.add(child)
                todo.append(child)
    if session:
        found.update(p for p, (_, sid) in table.items() if sid == pid)
    found.discard(pid)
    return sorted(found)


def session_members(sid: int) -> list[int]:
    """The living processes of session ``sid`` other than its leader."""
    return sorted(p for p, (_, s) in _process_table().items() if s == sid and p != sid)


def _gone(pid: int) -> bool:
    """Whether ``pid`` has exited (no entry in ``/proc``, or a zombie waiting to be reaped)."""
    try:
        text = (_PROC / str(pid) / "stat").read_text()
    except OSError:
        return True
    return text[text.rindex(")") + 2:].split()[0] in ("Z", "X")


def end_processes(pids, *, within_s: float = 2.0) -> list[int]:
    """Kill ``pids`` with ``SIGKILL`` (what they are cannot matter: an agent's process that
    outlives its episode is ended, not asked) and wait up to ``within_s`` until each has exited,
    reaping those that are children of this process; returns the pids that were signalled.
    (A zombie left is another process's child: its parent reaps it, or init once that parent
    is gone.)"""
    ended = []
    for pid in sorted(set(pids)):
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            continue
        except PermissionError:  # not ours to end
            _log.warning("process %d outlived its episode and cannot be ended: permission denied", pid)
            continue
        ended.append(pid)
    waiting = list(ended)
    deadline = time.monotonic() + within_s
    while waiting:
        for pid in list(waiting):
            try:
                os.waitpid(pid, os.WNOHANG)
            except ChildProcessError:  # not our child: its own parent (or init) reaps it
                pass
            if _gone(pid):
                waiting.remove(pid)
        if not waiting or time.monotonic() > deadline:
            break
        time.sleep(0.01)
    return ended


def allocated_mib(pid: int) -> float | None:
    """The memory process ``pid`` has allocated, in MiB: its anonymous and shared-memory resident
    pages and what of them is swapped out (``RssAnon + RssShmem + VmSwap`` of
    ``/proc/PID/status``: heap, arrays, tensors, ``/dev/shm``), not the files it maps (libraries,
    read-only data, which the kernel can drop and reload). Reading it costs a few microseconds
    (kernel counters), where ``/proc/PID/smaps_rollup`` walks every mapping (milliseconds for a
    worker with torch loaded). A forked process starts with its parent's pages counted here,
    shared until written; the pool subtracts what a worker held when it started. None when the
    process is gone or has no such counters (not Linux, a kernel before 4.5)."""
    try:
        text = (_PROC / str(pid) / "status").read_text()
    except OSError:
        return None
    kib, seen = 0, 0
    for line in text.splitlines():
        key, _, value = line.partition(":")
        if key in ("RssAnon", "RssShmem", "VmSwap"):
            kib += int(value.split()[0])
            seen += 1
    return kib / 1024.0 if seen else None


def reads_memory() -> bool:
    """Whether :func:`allocated_mib` can read processes' memory here (it reads this one's)."""
    return allocated_mib(os.getpid()) is not None


def become_child_subreaper() -> bool:
    """Make this process the reaper of the orphans below it (Linux ``PR_SET_CHILD_SUBREAPER``),
    so that a grandchild whose parent exited (a double fork) stays below it and
    :func:`descendants` finds it; False where that cannot be set."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(_PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


def reap_children() -> int:
    """Reap every child of this process that has exited (``waitpid`` without blocking); how many."""
    reaped = 0
    while True:
        try:
            pid, _ = os.waitpid(-1, os.WNOHANG)
        except ChildProcessError:
            return reaped
        if pid == 0:
            return reaped
        reaped += 1
