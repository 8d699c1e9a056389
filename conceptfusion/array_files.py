"""Checking an ``.npz`` archive's array headers before numpy allocates anything.

``np.load`` trusts each member's ``.npy`` header: a 1 KB file whose header claims ``10**11``
elements makes numpy allocate for them (``MemoryError``, or the machine swapping) before it
finds the data missing. :func:`check_npz_headers` reads only the zip directory and each
member's header and refuses a member whose claimed shape and dtype do not match the bytes it
actually holds, naming the member, the claimed shape and the actual size.
"""

from __future__ import annotations

import math
import os
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.lib import format as npy_format

__all__ = ["MAX_NPZ_BYTES", "MAX_DEFLATE_RATIO", "NpyHeader", "check_npz_headers"]

MAX_NPZ_BYTES = 64 * 2**30
"""Largest total of the arrays in one archive (uncompressed): 64 GiB, far above any map or
recording the project writes (a 1M-point map with 512-d features is about 2 GiB)."""

MAX_DEFLATE_RATIO = 1100
"""Largest uncompressed-to-compressed size ratio a compressed member may claim (deflate cannot
exceed about 1032); a member claiming more is a zip bomb or a lying directory."""


@dataclass(frozen=True)
class NpyHeader:
    """What one member's ``.npy`` header claims."""

    name: str
    """The member's name in the archive (``"geometry.npy"``)."""
    shape: tuple[int, ...]
    dtype: np.dtype
    data_bytes: int
    """The bytes the member actually holds after its header."""


def _read_header(f, version: tuple[int, int]):
    if version == (1, 0):
        return npy_format.read_array_header_1_0(f)
    if version == (2, 0):
        return npy_format.read_array_header_2_0(f)
    raise ValueError(f"unsupported .npy format version {version[0]}.{version[1]}")


def check_npz_headers(path: str | os.PathLike, error: type[Exception], *, max_bytes: int = MAX_NPZ_BYTES,
                      what: str = "archive") -> dict[str, NpyHeader]:
    """The header of every ``.npy`` member of the ``.npz`` archive at ``path``, by member name,
    after checking that nothing in it can make ``np.load`` allocate more than the file holds.

    Raises ``error`` naming the file and the member for: a member whose directory entry claims
    more bytes than the archive has (stored) or than deflate can give (compressed), members
    totalling more than ``max_bytes``, a member that holds Python objects (pickles), or a
    header whose shape times item size differs from the bytes that follow it (the claimed shape
    and dtype and the actual bytes are named). ``zipfile.BadZipFile`` passes through for a file
    that is not a zip archive at all.
    """
    p = Path(path)
    archive_bytes = os.stat(p).st_size
    out: dict[str, NpyHeader] = {}
    total = 0
    with zipfile.ZipFile(p) as zf:
        for info in zf.infolist():
            name = info.filename
            stored = info.compress_type == zipfile.ZIP_STORED
            if info.compress_size > archive_bytes or (stored and info.file_size != info.compress_size) or (
                not stored and info.file_size > MAX_DEFLATE_RATIO * max(info.compress_size, 1)
            ):
                raise error(f"{p}: not a readable {what}: member {name!r} claims {info.file_size} bytes "
                            f"({info.compress_size} compressed) in a file of {archive_bytes} bytes")
            total += info.file_size
            if total > max_bytes:
                raise error(f"{p}: not a readable {what}: its members hold more than {max_bytes} bytes "
                            f"(limit MAX_NPZ_BYTES); at member {name!r}, {total} bytes")
            if not name.endswith(".npy"):
                continue
            with zf.open(info) as f:
                try:
                    version = npy_format.read_magic(f)
                except ValueError:
                    continue  # not an array: np.load reads it as bytes, bounded by the checks above
                try:
                    shape, _, dtype = _read_header(f, version)
                except ValueError as exc:
                    raise error(f"{p}: not a readable {what}: member {name!r} has a corrupt array header ({exc})") from None
                header_bytes = f.tell()
            if dtype.hasobject:
                raise error(f"{p}: not a readable {what}: an entry holds Python objects (member {name!r}, dtype "
                            f"{dtype}), which a {what} never does")
            claimed = math.prod(shape) * dtype.itemsize
            actual = info.file_size - header_bytes
            if claimed != actual:
                raise error(f"{p}: not a readable {what}: member {name!r} claims shape {tuple(shape)} of {dtype} "
                            f"({claimed} bytes), but holds {actual} bytes of data")
            out[name] = NpyHeader(name, tuple(shape), dtype, actual)
    return out
