"""Atomic file writes (a reader never sees a half-written file), and reading user-provided files
with clear errors.

Readers open only regular files (after following symlinks: a FIFO would block ``open`` and
``read`` forever, ``/dev/zero`` would be read until memory runs out) and check the size against
a limit per kind of file *before* reading. The limits are generous (tens to hundreds of times
the largest file the project writes) and meant to stop a wrong or hostile path, not real data:

========================  ==========================================  ==========
kind                      files                                       limit
========================  ==========================================  ==========
:data:`MAX_SCENE_BYTES`   scene files (``scenes/**/*.json``)          256 MiB
:data:`MAX_EPISODES_BYTES` episode files (``*.jsonl``)                 256 MiB
:data:`MAX_RESULTS_BYTES` ``results.jsonl`` of a run                   4 GiB
:data:`MAX_DOCUMENT_BYTES` small JSON documents: ``run.json``, splits,  64 MiB
                          the sealed manifest, bounds
========================  ==========================================  ==========
"""

from __future__ import annotations

import os
import stat
import shutil
import tempfile
from pathlib import Path

from conceptfusion.errors import MissingFileError

__all__ = [
    "atomic_write_bytes", "atomic_copy", "atomic_write_text", "read_text_file", "read_json_file", "read_json_document", "read_file_bytes",
    "check_regular_file", "MAX_SCENE_BYTES", "MAX_EPISODES_BYTES", "MAX_RESULTS_BYTES", "MAX_DOCUMENT_BYTES",
]

MAX_SCENE_BYTES = 256 * 2**20
"""Largest scene file read (a 10,000-object scene is about 3 MB)."""
MAX_EPISODES_BYTES = 256 * 2**20
"""Largest episode file read (the shipped ones are under 100 KB)."""
MAX_RESULTS_BYTES = 4 * 2**30
"""Largest ``results.jsonl`` read (a record is about 1 KB: some four million episodes)."""
MAX_DOCUMENT_BYTES = 64 * 2**20
"""Largest small JSON document read: run settings, split files, the sealed manifest, the regression bounds."""

_KINDS = ((stat.S_ISDIR, "folder"), (stat.S_ISFIFO, "FIFO (named pipe)"), (stat.S_ISCHR, "character device"),
          (stat.S_ISBLK, "block device"), (stat.S_ISSOCK, "socket"))


def _article(what: str) -> str:
    return "an" if what[:1].lower() in "aeiou" else "a"


def _kind_of(mode: int) -> str:
    for test, name in _KINDS:
        if test(mode):
            return name
    return "special file"


def _check_stat(p: Path, st: os.stat_result, what: str, error: type[Exception], max_bytes: int) -> None:
    if not stat.S_ISREG(st.st_mode):
        link = f" (a symlink to {os.path.realpath(p)})" if p.is_symlink() else ""
        regular = "" if stat.S_ISDIR(st.st_mode) else "; only regular files are read"
        raise error(f"{p}: expected {_article(what)} {what}, got a {_kind_of(st.st_mode)}{link}{regular}")
    if st.st_size > max_bytes:
        raise error(f"{p}: expected {_article(what)} {what} of at most {max_bytes} bytes, got {st.st_size} bytes")


def check_regular_file(path: str | os.PathLike, what: str, error: type[Exception], max_bytes: int) -> os.stat_result:
    """The ``os.stat`` of ``path`` (symlinks followed) if it is a regular file of at most
    ``max_bytes`` bytes; ``what`` names the file in messages (``"scene file"``).

    Raises :class:`~conceptfusion.errors.MissingFileError` when there is no such file, and
    ``error`` naming the file for a folder, FIFO, device or socket, or a file over the limit.
    Nothing is opened, so a FIFO cannot block.
    """
    p = Path(path)
    try:
        st = os.stat(p)
    except FileNotFoundError:
        raise MissingFileError(f"{what} not found: {p}") from None
    _check_stat(p, st, what, error, max_bytes)
    return st


def read_file_bytes(path: str | os.PathLike, what: str, error: type[Exception], max_bytes: int) -> bytes:
    """The bytes of the regular file at ``path`` (see :func:`check_regular_file`), read only
    after the checks: the file is opened without blocking and checked again on the open
    descriptor (it may have been swapped for a FIFO since), and never more than ``max_bytes``
    bytes are read (it may have grown)."""
    p = Path(path)
    check_regular_file(p, what, error, max_bytes)
    try:
        fd = os.open(p, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        raise MissingFileError(f"{what} not found: {p}") from None
    with os.fdopen(fd, "rb") as f:
        st = os.fstat(f.fileno())
        _check_stat(p, st, what, error, max_bytes)
        chunks, size = [], 0
        while size <= max_bytes:  # read(n) would reserve n bytes up front: ask for what is there
            chunk = f.read(max(st.st_size - size, 0) + 1 if not chunks else 1 << 20)
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
        data = chunks[0] if len(chunks) == 1 else b"".join(chunks)
    if len(data) > max_bytes:
        raise error(f"{p}: expected {_article(what)} {what} of at most {max_bytes} bytes, got more (it grew while read)")
    return data


def _atomic_write(path: str | os.PathLike, write) -> Path:
    """Call ``write(f)`` on a temporary file beside ``path`` (binary), fsync it and rename it to
    ``path``; the temporary file is removed when anything fails. Creates missing parent folders."""
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    try:
        os.fchmod(fd, 0o666 & ~_umask())  # mkstemp creates 0600; give the usual file mode
        with os.fdopen(fd, "wb") as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, target)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
    return target


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (temporary file in the same folder, fsync, rename).

    Creates missing parent folders. Returns the path written.
    """
    return _atomic_write(path, lambda f: f.write(data))


def atomic_copy(src: str | os.PathLike, dst: str | os.PathLike) -> Path:
    """Copy the file ``src`` to ``dst`` atomically, streamed (a map file can be hundreds of MB):
    a temporary file beside ``dst``, fsync, rename. Creates missing parent folders. Returns ``dst``."""
    with open(src, "rb") as inp:
        return _atomic_write(dst, lambda f: shutil.copyfileobj(inp, f, 1 << 20))


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write_text(path: str | os.PathLike, text: str) -> Path:
    """Write UTF-8 ``text`` to ``path`` atomically (see :func:`atomic_write_bytes`)."""
    return atomic_write_bytes(path, text.encode("utf-8"))


def read_text_file(path: str | os.PathLike, what: str, error: type[Exception], *,
                   max_bytes: int = MAX_DOCUMENT_BYTES) -> str:
    """The UTF-8 text of the file at ``path``, which should hold ``what`` (``"scene file"``).

    Raises :class:`~conceptfusion.errors.MissingFileError` when there is no such file, and
    ``error`` naming the file for a folder, a FIFO, a device or another special file (symlinks
    are followed first), a file of more than ``max_bytes`` bytes, or bytes that are not UTF-8
    (with the line and byte offset of the first bad byte).
    """
    p = Path(path)
    article = _article(what)
    data = read_file_bytes(p, what, error, max_bytes)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        raise error(f"{p}:line {line}: not {article} {what}: not UTF-8 text "
                    f"(byte 0x{data[exc.start]:02x} at offset {exc.start})") from None


def read_json_file(path: str | os.PathLike, what: str, error: type[Exception], *, max_bytes: int = MAX_DOCUMENT_BYTES):
    """The JSON value in the file at ``path`` (:func:`read_text_file`, then
    :func:`conceptfusion.strict_json.loads_strict`: duplicate keys, too deep nesting and huge
    integers refused with ``error``, naming the file). Text that is not JSON raises
    ``json.JSONDecodeError`` as ``json.loads`` does, for the caller to word."""
    from conceptfusion.strict_json import loads_strict

    return loads_strict(read_text_file(path, what, error, max_bytes=max_bytes), source=str(path), error=error)


def read_json_document(path: str | os.PathLike, *, fmt: str, version: int, what: str, missing: str,
                       error: type[Exception], max_bytes: int = MAX_DOCUMENT_BYTES) -> dict:
    """The JSON object in the file at ``path``, whose ``format`` must be ``fmt`` and ``version``
    ``version``; ``what`` names the document in messages ("split file"), ``missing`` is the message
    for a file that is not there.

    Raises:
        error: no such file (``missing``), not a regular file or over ``max_bytes``, not JSON, a
            duplicate key, too deep nesting or a huge integer
            (:func:`conceptfusion.strict_json.loads_strict`), or another format or version
            (naming the file).
    """
    import json

    p = Path(path)
    try:
        data = read_json_file(p, what, error, max_bytes=max_bytes)
    except FileNotFoundError:
        raise error(f"{p}: {missing}") from None
    except json.JSONDecodeError as exc:
        raise error(f"{p}: not a JSON {what} ({exc})") from None
    if not isinstance(data, dict) or data.get("format") != fmt or data.get("version") != version:
        raise error(f"{p}: expected format {fmt!r} version {version}")
    return data
