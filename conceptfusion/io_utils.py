"""Atomic file writes (a reader never sees a half-written file), and reading text files with
clear errors."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from conceptfusion.errors import MissingFileError

__all__ = ["atomic_write_bytes", "atomic_write_text", "read_text_file", "read_json_document"]


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (temporary file in the same folder, fsync, rename).

    Creates missing parent folders. Returns the path written.
    """
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    try:
        os.fchmod(fd, 0o666 & ~_umask())  # mkstemp creates 0600; give the usual file mode
        with os.fdopen(fd, "wb") as f:
            f.write(data)
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


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write_text(path: str | os.PathLike, text: str) -> Path:
    """Write UTF-8 ``text`` to ``path`` atomically (see :func:`atomic_write_bytes`)."""
    return atomic_write_bytes(path, text.encode("utf-8"))


def read_text_file(path: str | os.PathLike, what: str, error: type[Exception]) -> str:
    """The UTF-8 text of the file at ``path``, which should hold ``what`` (``"scene file"``).

    Raises :class:`~conceptfusion.errors.MissingFileError` when there is no such file, and
    ``error`` naming the file for a folder, a special file, or bytes that are not UTF-8 (with the
    line and byte offset of the first bad byte).
    """
    p = Path(path)
    article = "an" if what[:1].lower() in "aeiou" else "a"
    if not p.is_file():
        if p.exists():
            raise error(f"{p}: expected {article} {what}, got a {'folder' if p.is_dir() else 'special file'}")
        raise MissingFileError(f"{what} not found: {p}")
    data = p.read_bytes()
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        raise error(f"{p}:line {line}: not {article} {what}: not UTF-8 text "
                    f"(byte 0x{data[exc.start]:02x} at offset {exc.start})") from None


def read_json_document(path: str | os.PathLike, *, fmt: str, version: int, what: str, missing: str,
                       error: type[Exception]) -> dict:
    """The JSON object in the file at ``path``, whose ``format`` must be ``fmt`` and ``version``
    ``version``; ``what`` names the document in messages ("split file"), ``missing`` is the message
    for a file that is not there.

    Raises:
        error: no such file (``missing``), not JSON, or another format or version (naming the file).
    """
    import json

    p = Path(path)
    try:
        data = json.loads(p.read_text())
    except FileNotFoundError:
        raise error(f"{p}: {missing}") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise error(f"{p}: not a JSON {what} ({exc})") from None
    if not isinstance(data, dict) or data.get("format") != fmt or data.get("version") != version:
        raise error(f"{p}: expected format {fmt!r} version {version}")
    return data
