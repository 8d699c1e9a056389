"""A run folder: checked before a run starts, and owned by one run at a time.

:func:`check_run_folder` refuses an ``--out`` that cannot be a run folder (an empty path, a
file, a path under a file, a folder this user cannot write in) without writing anything.

:func:`lock_run_folder` takes an exclusive ``fcntl.flock`` on :data:`LOCK_FILE` inside the
folder for the life of the run, and writes who holds it (pid, host, run id, start time) into
the file. A second process that tries to take it is refused at once with
:class:`RunFolderBusyError` naming the holder (:func:`refuse_if_busy` asks without writing).
The operating system drops the lock when the holding process exits, however it exits
(``SIGKILL`` included), so a lock file left behind by a dead run never blocks: only the lock
blocks, never the file's content.

The lock belongs to the process: a process that plans the same folder twice (tests, a notebook
that plans, then resumes) shares one lock, counted, and the folder is free once every
:class:`RunLock` of it is released (or the process ends). The holder's line is rewritten in
place on the locked descriptor, not by an atomic rename: a rename would put a new file (a new
lock) in place of the one other processes lock.

A run folder whose file system fills up (or turns read-only) during a run is not a bad setting
but a stop: :func:`writing` turns such an ``OSError`` (:data:`NO_ROOM_ERRNOS`) into
:class:`RunFolderFullError`, naming what could not be written, for ``cfharness run`` to word
with the command that resumes the run.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import os
import socket
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path

from conceptfusion.errors import ConceptFusionError, HarnessError

__all__ = ["LOCK_FILE", "NO_ROOM_ERRNOS", "RunFolderBusyError", "RunFolderFullError", "RunLock", "check_run_folder",
           "lock_run_folder", "refuse_if_busy", "writing"]

LOCK_FILE = ".cfharness.lock"
"""Name of the lock file inside a run folder."""
NO_ROOM_ERRNOS = frozenset(e for e in (errno.ENOSPC, getattr(errno, "EDQUOT", None), errno.EROFS) if e is not None)
"""``errno`` values that say the file system takes no more writes: full, over quota, read-only."""


class RunFolderBusyError(HarnessError):
    """Another process's run holds the run folder."""


class RunFolderFullError(ConceptFusionError, OSError):
    """Something of a run could not be written because its file system is full, over quota or
    read-only (an ``errno`` of :data:`NO_ROOM_ERRNOS`, kept as this error's ``errno``). An
    ``OSError``, not a :class:`~conceptfusion.errors.HarnessError` (a ``ValueError``): it is no
    bad setting, and the run it stops can be resumed once there is room.

    Attributes:
        what: what could not be written, in words ("a results record", "run.json", "the report").
        filename: its path.
    """

    def __init__(self, what: str, path, cause: OSError) -> None:
        super().__init__(cause.errno, cause.strerror or os.strerror(cause.errno), str(path))
        self.what = what


@contextlib.contextmanager
def writing(what: str, path):
    """Within the block, an ``OSError`` of :data:`NO_ROOM_ERRNOS` becomes
    :class:`RunFolderFullError` naming ``what`` (in words) and ``path``; others pass unchanged."""
    try:
        yield
    except RunFolderFullError:
        raise
    except OSError as exc:
        if exc.errno not in NO_ROOM_ERRNOS:
            raise
        raise RunFolderFullError(what, path, exc) from exc


@dataclass
class _Held:
    """This process's lock on one run folder: the locked descriptor and how many holders share it."""

    fd: int
    count: int = 0


_HELD: dict[str, _Held] = {}
"""Resolved run folder -> this process's lock on it."""


@dataclass
class RunLock:
    """A held run folder (see :func:`lock_run_folder`); :meth:`release` gives it up (idempotent)."""

    run_dir: Path
    key: str
    released: bool = field(default=False)

    def release(self) -> None:
        """Give up this hold; the folder is free once this process holds it no more."""
        if self.released:
            return
        self.released = True
        held = _HELD.get(self.key)
        if held is None:
            return
        held.count -= 1
        if held.count <= 0:
            del _HELD[self.key]
            os.close(held.fd)  # closing the descriptor drops the flock

    def __enter__(self) -> "RunLock":
        return self

    def __exit__(self, *exc) -> None:
        self.release()


def check_run_folder(run_dir) -> Path:
    """``run_dir`` as a ``Path``, once it can be a run folder; writes nothing.

    Raises:
        HarnessError: an empty path, a path that is a file or lies under a file, or a folder
            (or, for a folder still to be made, its nearest existing parent) that this user
            cannot write in (``os.access``: as root, permissions do not refuse; a read-only file
            system does, and the message says so).
    """
    if not isinstance(run_dir, (str, os.PathLike)) or not str(run_dir).strip():
        raise HarnessError(f"--out: expected a folder path, got {run_dir!r}")
    p = Path(run_dir)
    if p.exists() and not p.is_dir():
        raise HarnessError(f"--out {run_dir}: expected a folder, got a file")
    existing = p
    while not existing.exists():
        if existing.parent == existing:
            break
        existing = existing.parent
    if existing != p and not existing.is_dir():
        raise HarnessError(f"--out {run_dir}: expected a folder path, but {existing} is a file, so no folder can be made there")
    if not os.access(existing, os.W_OK | os.X_OK):
        where = "this folder" if existing == p else f"{existing}, where it would be made,"
        why = " (a read-only file system)" if _read_only(existing) else ""
        raise HarnessError(f"--out {run_dir}: expected a folder this user can write in, but {where} is not writable{why}")
    return p


def _read_only(folder: Path) -> bool:
    """Whether ``folder`` lies on a file system mounted read-only (False when that cannot be told)."""
    try:
        return bool(os.statvfs(folder).f_flag & getattr(os, "ST_RDONLY", 0))
    except OSError:
        return False


def _holder(fd: int) -> str:
    """Who holds the lock, in words, from the lock file's content ('unknown' when unreadable)."""
    try:
        os.lseek(fd, 0, os.SEEK_SET)
        info = json.loads(os.read(fd, 4096).decode("utf-8"))
        return (f"pid {info['pid']} on host {info['host']}, run id {info.get('run_id') or 'not yet chosen'}, "
                f"started {info['started']}")
    except (OSError, ValueError, KeyError, TypeError):
        return "a process that has not written its name yet"


def _busy(run_dir: Path, fd: int) -> RunFolderBusyError:
    return RunFolderBusyError(f"--out {run_dir}: expected a run folder no other run is using, but another cfharness run "
                              f"holds it ({_holder(fd)}); wait for it to end or choose another --out")


def refuse_if_busy(run_dir) -> None:
    """Raise :class:`RunFolderBusyError` naming the holder when another process holds ``run_dir``;
    writes nothing (a folder or lock file that does not exist is free)."""
    p = Path(run_dir)
    if str(p.resolve()) in _HELD:
        return
    try:
        fd = os.open(p / LOCK_FILE, os.O_RDONLY)
    except OSError:
        return
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise _busy(p, fd) from None
        except OSError:  # a file system without flock: nothing to tell
            return
        fcntl.flock(fd, fcntl.LOCK_UN)
    finally:
        os.close(fd)


def lock_run_folder(run_dir, run_id: str | None = None) -> RunLock:
    """Make ``run_dir`` (and its parents) if needed and hold it for this process; writes the
    holder (pid, host, ``run_id``, start time) into :data:`LOCK_FILE`. A folder this process
    holds already is shared (the holder's line then names the newest ``run_id``).

    Raises:
        RunFolderBusyError: another process holds it (naming pid, host, run id and start time).
        HarnessError: the folder or its lock file cannot be made (naming the path and the reason).
        RunFolderFullError: they cannot be written because the file system is full, over quota
            or read-only.
    """
    p = check_run_folder(run_dir)
    try:
        p.mkdir(parents=True, exist_ok=True)
        key = str(p.resolve())
        held = _HELD.get(key)
        if held is None:
            fd = os.open(p / LOCK_FILE, os.O_RDWR | os.O_CREAT, 0o666)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                err = _busy(p, fd)
                os.close(fd)
                raise err from None
            except OSError as exc:
                os.close(fd)
                if exc.errno not in (errno.ENOLCK, errno.EOPNOTSUPP, errno.EINVAL):
                    raise
                raise HarnessError(f"--out {run_dir}: expected a file system that supports locks (flock), got "
                                   f"{exc.strerror}; choose a local --out") from exc
            held = _HELD[key] = _Held(fd)
        held.count += 1
        lock = RunLock(p, key)
        info = {"pid": os.getpid(), "host": socket.gethostname(), "run_id": run_id,
                "started": datetime.now(timezone.utc).isoformat(timespec="seconds")}
        data = (json.dumps(info) + "\n").encode("utf-8")
        try:
            os.ftruncate(held.fd, 0)
            os.pwrite(held.fd, data, 0)
            os.fsync(held.fd)
        except OSError:
            lock.release()
            raise
    except OSError as exc:
        if exc.errno in NO_ROOM_ERRNOS:
            raise RunFolderFullError("the run folder's lock file", p / LOCK_FILE, exc) from exc
        raise HarnessError(f"--out {run_dir}: expected a run folder this process can make and write, got "
                           f"{exc.strerror or exc} ({exc.filename or p})") from exc
    return lock
