"""Strict JSON parsing for user-provided files: duplicate keys, deep nesting and huge integers
are refused with a message naming the file, the line and the key, before they do harm.

``json.loads`` alone keeps the last of two equal keys (a scene with ``"objects"`` twice loads
with the second list, possibly empty), recurses until ``RecursionError`` on deep nesting, and
raises Python's bare ``ValueError`` about ``sys.set_int_max_str_digits`` for an integer of more
than 4300 digits. :func:`loads_strict` answers each of these with the caller's error class.

The common case stays at C speed: duplicate keys are found by a small ``object_pairs_hook``;
nesting is measured (with numpy, outside strings) only when the text holds more brackets than
the depth limit; the line and key of a fault are worked out only after one was found.
"""

from __future__ import annotations

import json
import re
from json.decoder import JSONArray, JSONObject
from types import SimpleNamespace

import numpy as np

from conceptfusion.errors import ConceptFusionError

__all__ = ["MAX_JSON_DEPTH", "MAX_INT_DIGITS", "loads_strict", "nesting_depth"]

MAX_JSON_DEPTH = 100
"""Deepest nesting of arrays and objects accepted. The project's files nest at most 6 deep
(a scene: document, ``rooms``, room, ``floor``, corner); 100 leaves room for user data in
``extras`` and stays far below the interpreter's recursion limit."""

MAX_INT_DIGITS = 40
"""Longest integer accepted, in decimal digits (a 128-bit integer has 39). Seeds and counts are
far shorter; a longer one is a corrupt or hostile file, and past 4300 digits Python refuses it
with a message that names neither the file nor the field."""

_STRING = re.compile(r'"(?:[^"\\\n]|\\.)*"')
_KEY_BEFORE = re.compile(r'"((?:[^"\\]|\\.)*)"\s*:')


class _Fault(ConceptFusionError, ValueError):
    """A fault found while parsing; never leaves :func:`loads_strict`, which turns it into the
    caller's error with a location."""

    def __init__(self, kind: str, detail, offset: int | None = None):
        super().__init__(kind)
        self.kind, self.detail, self.offset = kind, detail, offset


def _pairs(pairs: list) -> dict:
    d = dict(pairs)
    if len(d) != len(pairs):
        seen = set()
        for k, _ in pairs:
            if k in seen:
                raise _Fault("duplicate", k)
            seen.add(k)
    return d


def _int(digits: str) -> int:
    if len(digits.lstrip("-")) > MAX_INT_DIGITS:
        raise _Fault("bigint", digits)
    return int(digits)


def _refuse_constant(name: str):
    raise _Fault("constant", name)


def nesting_depth(text: str) -> tuple[int, int]:
    """The deepest nesting of ``[`` and ``{`` outside strings in the JSON ``text``, and the line
    (1-based) where it is first reached (``(0, 1)`` for text without brackets)."""
    stripped = _STRING.sub('""', text)  # JSON strings hold no raw newline: line numbers are kept
    b = np.frombuffer(stripped.encode("utf-8", "surrogatepass"), np.uint8)
    if b.size == 0:
        return 0, 1
    step = ((b == 0x5B) | (b == 0x7B)).astype(np.int32) - ((b == 0x5D) | (b == 0x7D))
    depth = np.cumsum(step)
    at = int(np.argmax(depth))
    return int(depth[at]), int(np.count_nonzero(b[:at] == 0x0A)) + 1


def _line_of(text: str, offset: int) -> int:
    return text.count("\n", 0, max(offset, 0)) + 1


def _key_before(text: str, offset: int) -> str | None:
    """The last ``"key":`` before ``offset`` (within 4 KB): the field a value belongs to."""
    window = text[max(0, offset - 4096) : offset]
    found = None
    for found in _KEY_BEFORE.finditer(window):
        pass
    return None if found is None else found.group(1)


def _object_start_of_duplicate(text: str, allow_nan: bool) -> int | None:
    """Re-parse with the pure-Python scanner (slow; only after a duplicate key was found) to
    find the offset of the object that holds the duplicate."""

    def parse_object(s_and_end, strict, scan_once, object_hook, object_pairs_hook, memo=None, *rest):
        start = s_and_end[1] - 1

        def hook(pairs):
            try:
                return _pairs(pairs)
            except _Fault as fault:
                fault.offset = start if fault.offset is None else fault.offset
                raise

        return JSONObject(s_and_end, strict, scan_once, object_hook, hook, memo, *rest)

    ctx = SimpleNamespace(
        parse_object=parse_object, parse_array=JSONArray, parse_string=json.decoder.scanstring, strict=True,
        object_hook=None, object_pairs_hook=None, parse_float=float, parse_int=int,
        parse_constant=json.decoder._CONSTANTS.__getitem__ if allow_nan else _refuse_constant, memo={},
    )
    scan = json.scanner.py_make_scanner(ctx)
    try:
        scan(text, len(text) - len(text.lstrip()))
    except _Fault as fault:
        return fault.offset
    except Exception:  # noqa: BLE001 - best effort: only the location is missing then
        return None
    return None


def loads_strict(text: str, *, source: str, error: type[Exception], line: int | None = None, allow_nan: bool = True,
                 max_depth: int = MAX_JSON_DEPTH):
    """Parse the JSON ``text`` read from ``source`` (a path), refusing what ``json.loads`` lets by.

    ``line`` is the file's line number of ``text`` when it is one line of a JSON Lines file;
    otherwise the line is counted within ``text``. ``allow_nan=False`` also refuses ``NaN``,
    ``Infinity`` and ``-Infinity``.

    Raises:
        error: ``"{source}:line {n}: ..."`` for a key that appears twice in one object (naming
            the key), nesting deeper than ``max_depth`` (:data:`MAX_JSON_DEPTH`), an integer of
            more than :data:`MAX_INT_DIGITS` digits (naming the field it belongs to) or, with
            ``allow_nan=False``, a NaN or infinity.
        json.JSONDecodeError: for text that is not JSON, unchanged, so callers keep their
            messages (and the results reader its half-written-line handling).
    """

    def where(offset: int | None) -> str:
        if line is not None:
            return f"{source}:line {line}"
        return f"{source}" if offset is None else f"{source}:line {_line_of(text, offset)}"

    if text.count("[") + text.count("{") > max_depth:
        depth, depth_line = nesting_depth(text)
        if depth > max_depth:
            at_line = depth_line if line is None else line
            raise error(f"{source}:line {at_line}: JSON nested {depth} levels deep; expected at most {max_depth} "
                        "(arrays and objects inside one another)")
    try:
        return json.loads(text, object_pairs_hook=_pairs, parse_int=_int,
                          **({} if allow_nan else {"parse_constant": _refuse_constant}))
    except _Fault as fault:
        if fault.kind == "duplicate":
            start = _object_start_of_duplicate(text, allow_nan)
            raise error(f"{where(start)}: duplicate key {fault.detail!r} in one JSON object (opened on this line); "
                        "expected each key once (a JSON reader would silently keep only the last value)") from None
        if fault.kind == "bigint":
            digits = fault.detail
            offset = text.find(digits)
            key = _key_before(text, offset) if offset >= 0 else None
            field = f"field {key!r}: " if key is not None else ""
            raise error(f"{where(offset if offset >= 0 else None)}: {field}expected an integer of at most "
                        f"{MAX_INT_DIGITS} digits, got one of {len(digits.lstrip('-'))} digits "
                        f"({digits[:12]}...)") from None
        offset = text.find(fault.detail)
        key = _key_before(text, offset) if offset >= 0 else None
        field = f", in field {key!r}" if key is not None else ""
        raise error(f"{where(offset if offset >= 0 else None)}: not valid JSON ({fault.detail} is not a number JSON "
                    f"allows){field}") from None
    except RecursionError:  # a safety net: the depth check above should have refused it
        raise error(f"{where(None)}: JSON nested too deeply; expected at most {max_depth} levels") from None
