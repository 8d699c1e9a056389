"""The results store of an evaluation run: one JSON record per episode in ``results.jsonl``.

A record (one line, one JSON object)::

    {"format": "cf-results", "version": 1, "run_id": "...", "suite": "...", "task": "...",
     "agent": "map-navigator", "agent_kwargs": {"integrate_every": 3}, "encoder": "...",
     "episode_id": "...", "seed": 0, "status": "ok" | "failed" | "timeout", "error": null,
     "metrics": {"success": true, "spl": 0.71, ...}, "timings": {"wall_s": 3.2, ...},
     "category": "mug" | null, "extras": {...}, "harness_version": "0.1.0",
     "finished_at": "2025-01-01T00:00:00+00:00"}

Crash safety: :func:`append_record` writes each line with one ``os.write`` on an ``O_APPEND``
descriptor and fsyncs it, so a killed writer loses at most the line it was writing; a write that
fails (a full disk writes part of the line, then raises ``ENOSPC``) is cut back at once. Such a
half-written last line is skipped (with a warning) by :func:`load_results` and cut off by
:func:`repair_results` before a resumed run appends. Other damage is not what a killed writer
leaves: a record with a bad field (``"seed": "abc"``, ``"status": "weird"``, NaN) is always
refused, naming file, line and field; a junk line in the middle is skipped with a warning when
reading for a report, but :func:`repair_results` refuses it (naming the lines) so that a resumed
run never appends after junk.

The run's settings live next to the results in ``run.json`` (:func:`write_run_config`), so a
resumed run can check that it continues the same run; every record carries its ``run_id``, and
:func:`check_run_records` refuses, before a resumed run appends, a record of another run or two
records of one episode with different outcomes (naming file and lines).
"""

from __future__ import annotations

import json
import math
import os
import warnings
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

from conceptfusion.errors import HarnessError, MissingFileError
from conceptfusion.io_utils import (
    MAX_RESULTS_BYTES, atomic_write_text, check_regular_file, read_file_bytes, read_json_file,
)
from conceptfusion.strict_json import loads_strict

__all__ = [
    "RESULTS_FORMAT", "RESULTS_VERSION", "RUN_CONFIG_FORMAT", "RUN_CONFIG_VERSION", "RESULTS_FILE", "RUN_CONFIG_FILE",
    "STATUSES", "ResultsFormatError", "EpisodeKey", "agent_label", "record_key", "make_record", "append_record",
    "load_results", "repair_results", "completed_keys", "latest_records", "write_run_config", "read_run_config",
    "check_run_config", "check_run_records", "warn_record_problems", "harness_version", "load_runs",
]

RESULTS_FORMAT = "cf-results"
RESULTS_VERSION = 1
RUN_CONFIG_FORMAT = "cf-run"
RUN_CONFIG_VERSION = 1
RESULTS_FILE = "results.jsonl"
"""Name of the results file inside a run folder."""
RUN_CONFIG_FILE = "run.json"
"""Name of the run-settings file inside a run folder."""
STATUSES = ("ok", "failed", "timeout")

_REQUIRED = {
    "run_id": str, "suite": str, "task": str, "agent": str, "encoder": str, "episode_id": str, "seed": int,
    "status": str,
}
_OPTIONAL = {
    "agent_kwargs": (dict, dict), "error": ((str, type(None)), lambda: None), "metrics": (dict, dict),
    "timings": (dict, dict), "category": ((str, type(None)), lambda: None), "extras": (dict, dict),
}
_KEY_FIELDS = ("suite", "agent", "encoder", "episode_id", "seed")


class ResultsFormatError(HarnessError):
    """A results or run-settings file is corrupt, of another format or of a newer version, or a
    resumed run's settings differ from the stored ones."""


@dataclass(frozen=True)
class EpisodeKey:
    """Identifies one episode run, for resuming and for pairing agents.

    ``agent`` is the agent label (:func:`agent_label`): name plus its non-encoder arguments.
    """

    suite: str
    agent: str
    encoder: str
    episode_id: str
    seed: int


def _format_value(value) -> str:
    if isinstance(value, str):
        return value
    return json.dumps(value, sort_keys=True, separators=(",", ":"))


def agent_label(agent: str, agent_kwargs: dict | None = None) -> str:
    """Agent name plus its arguments other than ``encoder``, sorted by name.

    ``agent_label("map-navigator", {"integrate_every": 3, "encoder": "x"})`` is
    ``"map-navigator[integrate_every=3]"``; without such arguments it is the bare name.
    """
    if not isinstance(agent, str):
        raise TypeError(f"agent: expected a str, got {type(agent).__name__}")
    kwargs = {} if agent_kwargs is None else agent_kwargs
    if not isinstance(kwargs, dict):
        raise TypeError(f"agent_kwargs: expected a dict, got {type(kwargs).__name__}")
    parts = [f"{k}={_format_value(v)}" for k, v in sorted(kwargs.items()) if k != "encoder"]
    return f"{agent}[{','.join(parts)}]" if parts else agent


def record_key(record: dict) -> EpisodeKey:
    """The :class:`EpisodeKey` of a record (``KeyError``-free: a missing field is a ``ResultsFormatError``)."""
    missing = [k for k in _KEY_FIELDS if k not in record]
    if missing:
        raise ResultsFormatError(f"record: missing field(s) {missing}; got fields {sorted(record)}")
    return EpisodeKey(
        str(record["suite"]), agent_label(record["agent"], record.get("agent_kwargs") or {}), str(record["encoder"]),
        str(record["episode_id"]), int(record["seed"]),
    )


def harness_version() -> str:
    """Installed version of the ``conceptfusion-harness`` distribution, or ``"0+unknown"``."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("conceptfusion-harness")
    except PackageNotFoundError:
        return "0+unknown"


def _clean_metrics(metrics: dict) -> dict:
    out = {}
    for name, value in metrics.items():
        if not isinstance(name, str):
            raise TypeError(f"metrics: expected str names, got {name!r}")
        if value is None or isinstance(value, bool):
            out[name] = value
        elif isinstance(value, (int, float)) or hasattr(value, "item"):
            v = value.item() if hasattr(value, "item") else value
            if isinstance(v, bool):
                out[name] = v
            elif not isinstance(v, (int, float)):
                raise TypeError(f"metrics[{name!r}]: expected a number, bool or None, got {type(value).__name__}")
            else:
                out[name] = v if math.isfinite(v) else None
        else:
            raise TypeError(f"metrics[{name!r}]: expected a number, bool or None, got {type(value).__name__}")
    return out


def make_record(**fields) -> dict:
    """Build and validate one results record.

    Required: ``run_id, suite, task, agent, encoder, episode_id`` (str), ``seed`` (int),
    ``status`` (one of :data:`STATUSES`). Optional: ``agent_kwargs, metrics, timings, extras``
    (dict, default empty), ``error, category`` (str or None). ``format``, ``version``,
    ``harness_version`` and ``finished_at`` (UTC ISO 8601) are filled in. Metric values must be
    numbers, bools or None; NaN and infinities are stored as None (JSON has no NaN). numpy
    scalars are converted. The record must be JSON-serialisable.

    Raises ``TypeError``/``ValueError`` naming the field, what was expected and what arrived.
    """
    unknown = set(fields) - set(_REQUIRED) - set(_OPTIONAL) - {"format", "version", "harness_version", "finished_at"}
    if unknown:
        raise ValueError(f"make_record: unknown field(s) {sorted(unknown)}; expected some of "
                         f"{sorted(set(_REQUIRED) | set(_OPTIONAL))}")
    missing = [k for k in _REQUIRED if k not in fields]
    if missing:
        raise ValueError(f"make_record: missing required field(s) {missing}")
    if fields.get("format", RESULTS_FORMAT) != RESULTS_FORMAT or fields.get("version", RESULTS_VERSION) != RESULTS_VERSION:
        raise ValueError(f"make_record: format/version must be {RESULTS_FORMAT!r}/{RESULTS_VERSION}, got "
                         f"{fields.get('format')!r}/{fields.get('version')!r}")
    rec = {"format": RESULTS_FORMAT, "version": RESULTS_VERSION}
    for name, kind in _REQUIRED.items():
        value = fields[name]
        if kind is int and hasattr(value, "item") and not isinstance(value, bool):
            value = value.item()  # numpy integer
        if not isinstance(value, kind) or (kind is int and isinstance(value, bool)):
            raise TypeError(f"make_record: {name} expected {kind.__name__}, got {type(value).__name__} ({value!r})")
        rec[name] = value
    if rec["status"] not in STATUSES:
        raise ValueError(f"make_record: status expected one of {STATUSES}, got {rec['status']!r}")
    for name, (kind, default) in _OPTIONAL.items():
        value = fields.get(name, default())
        if not isinstance(value, kind):
            raise TypeError(f"make_record: {name} expected {kind}, got {type(value).__name__} ({value!r})")
        rec[name] = dict(value) if isinstance(value, dict) else value
    rec["metrics"] = _clean_metrics(rec["metrics"])
    for name, value in rec["timings"].items():
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise TypeError(f"make_record: timings[{name!r}] expected a float, got {type(value).__name__}")
        rec["timings"][name] = float(value)
    rec["harness_version"] = str(fields.get("harness_version") or harness_version())
    rec["finished_at"] = str(fields.get("finished_at") or datetime.now(timezone.utc).isoformat(timespec="seconds"))
    try:
        json.dumps(rec, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"make_record: record is not JSON-serialisable: {exc}") from exc
    return rec


def append_record(path: str | os.PathLike, record: dict) -> None:
    """Append one record as one line: a single ``os.write`` on an ``O_APPEND`` descriptor, then fsync.

    Creates missing parent folders. Safe for one writer process. Raises ``ResultsFormatError``
    when the file ends with a half-written line (call :func:`repair_results` first), so a new
    record is never glued onto a broken one. A write or fsync that fails (``OSError``: a full
    disk, ``ENOSPC``, writes part of a line first) cuts the file back to the length it had
    (cutting needs no free space) before the error is raised, so the file holds whole lines only;
    were the cut to fail too, the half-written last line is what :func:`repair_results` removes.
    """
    if not isinstance(record, dict):
        raise TypeError(f"record: expected a dict, got {type(record).__name__}")
    data = (json.dumps(record, allow_nan=False, separators=(",", ":")) + "\n").encode("utf-8")
    p = Path(path)
    if p.exists():  # opening a FIFO to write would wait for a reader forever
        check_regular_file(p, "results file", ResultsFormatError, MAX_RESULTS_BYTES)
    p.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(p, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o666)
    try:
        size = os.fstat(fd).st_size
        if size > 0:
            with open(p, "rb") as f:
                f.seek(size - 1)
                if f.read(1) != b"\n":
                    raise ResultsFormatError(f"{p}: ends with a half-written line; call repair_results({str(p)!r}) "
                                             "before appending")
        try:
            written = os.write(fd, data)
            while written < len(data):  # a short write: on a full disk, the next write raises ENOSPC
                written += os.write(fd, data[written:])
            os.fsync(fd)
        except OSError:
            _cut_back(fd, size)
            raise
    finally:
        os.close(fd)


def _cut_back(fd: int, size: int) -> None:
    """Truncate the file of ``fd`` to ``size`` bytes after a failed append (best effort: a file
    system that refuses even this leaves a half-written last line, which :func:`repair_results` cuts)."""
    try:
        os.ftruncate(fd, size)
    except OSError:
        pass


def _check_header(rec, where: str) -> None:
    if not isinstance(rec, dict):
        raise ResultsFormatError(f"{where}: expected a JSON object, got {type(rec).__name__}")
    fmt, version = rec.get("format"), rec.get("version")
    if fmt != RESULTS_FORMAT:
        raise ResultsFormatError(f"{where}: not a results record: format {fmt!r}, expected {RESULTS_FORMAT!r}")
    if isinstance(version, bool) or not isinstance(version, int) or version < 1:
        raise ResultsFormatError(f"{where}: bad version {version!r}; this code reads versions 1..{RESULTS_VERSION}")
    if version > RESULTS_VERSION:
        raise ResultsFormatError(f"{where}: written by results format version {version}, newer than the supported "
                                 f"version {RESULTS_VERSION}; upgrade conceptfusion-harness")


def _non_finite(value, path: str) -> str | None:
    """The path of the first NaN or infinite float inside ``value`` (JSON data), or None."""
    if isinstance(value, float):
        return None if math.isfinite(value) else path
    if isinstance(value, dict):
        items = value.items()
    elif isinstance(value, list):
        items = enumerate(value)
    else:
        return None
    for k, v in items:
        found = _non_finite(v, f"{path}[{k!r}]")
        if found:
            return found
    return None


def _check_record(rec: dict, where: str) -> None:
    """Every field of a parsed record, as :func:`make_record` writes them; ``ResultsFormatError``
    naming ``where`` (file and line) and the field otherwise."""
    allowed = set(_REQUIRED) | set(_OPTIONAL) | {"format", "version", "harness_version", "finished_at"}
    unknown = sorted(set(rec) - allowed)
    if unknown:
        raise ResultsFormatError(f"{where}: unknown field(s) {unknown}; a record holds {sorted(allowed)}")
    for name, kind in _REQUIRED.items():
        if name not in rec:
            raise ResultsFormatError(f"{where}: missing field {name!r}")
        value = rec[name]
        if not isinstance(value, kind) or isinstance(value, bool):
            raise ResultsFormatError(f"{where}: field {name!r}: expected {'an integer' if kind is int else 'a string'}, "
                                     f"got {value!r}")
    if rec["status"] not in STATUSES:
        raise ResultsFormatError(f"{where}: field 'status': expected one of {STATUSES}, got {rec['status']!r}")
    for name, (kind, _) in _OPTIONAL.items():
        if name in rec and not isinstance(rec[name], kind):
            expected = "an object" if kind is dict else "a string or null"
            raise ResultsFormatError(f"{where}: field {name!r}: expected {expected}, got {rec[name]!r}")
    for name in ("harness_version", "finished_at"):
        if name in rec and not isinstance(rec[name], str):
            raise ResultsFormatError(f"{where}: field {name!r}: expected a string, got {rec[name]!r}")
    for metric, value in rec.get("metrics", {}).items():
        if value is None or isinstance(value, bool):
            continue
        if not isinstance(value, (int, float)) or not math.isfinite(value):
            raise ResultsFormatError(f"{where}: field 'metrics[{metric!r}]': expected a finite number, true/false or "
                                     f"null, got {value!r}")
    for name, value in rec.get("timings", {}).items():
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise ResultsFormatError(f"{where}: field 'timings[{name!r}]': expected a finite number, got {value!r}")
    for name in ("agent_kwargs", "extras"):
        bad = _non_finite(rec.get(name), name)
        if bad:
            raise ResultsFormatError(f"{where}: field {bad!r}: NaN or infinity, which a record never holds")


def _describe(raw: bytes) -> str:
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        return "binary data"
    if "\0" in text:
        return "binary data"
    return f"text {text[:40]!r}" + ("..." if len(text) > 40 else "")


def _scan(data: bytes, where: str) -> tuple[list[dict], int, list[tuple[int, str]], str | None, list[int]]:
    """Parse the complete lines.

    Returns the records, the byte length of the good prefix (everything but a half-written last
    line), the corrupt lines elsewhere as ``(line number, reason)``, the warning about a
    half-written last line (None: there is none) and each record's line number. A line that is JSON but not a valid record
    raises ``ResultsFormatError`` (file, line, field) at once.
    """
    records: list[dict] = []
    numbers: list[int] = []
    corrupt: list[tuple[int, str]] = []
    lines = data.split(b"\n")
    complete_end = len(data) - len(lines[-1])  # bytes up to and including the last newline
    body, tail = lines[:-1], lines[-1]
    offset = 0
    good_end = 0
    for i, raw in enumerate(body, start=1):
        offset += len(raw) + 1
        if not raw.strip():
            good_end = offset
            continue
        try:
            rec = loads_strict(raw.decode("utf-8"), source=where, line=i, error=ResultsFormatError)
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            if i == len(body) and not tail.strip():
                return records, good_end, corrupt, f"{where}: line {i}: skipping a half-written last line ({exc})", numbers
            corrupt.append((i, f"{_describe(raw)}, not a JSON record ({exc})"))
            good_end = offset
            continue
        _check_header(rec, f"{where}: line {i}")
        _check_record(rec, f"{where}: line {i}")
        records.append(rec)
        numbers.append(i)
        good_end = offset
    if tail.strip():
        return (records, good_end, corrupt, f"{where}: line {len(body) + 1}: skipping a half-written last line (no newline)",
                numbers)
    if good_end == complete_end:
        good_end = len(data)  # keep trailing whitespace after the last newline
    return records, good_end, corrupt, None, numbers


def _read(p: Path) -> bytes:
    return read_file_bytes(p, "results file", ResultsFormatError, MAX_RESULTS_BYTES)


def load_results(path: str | os.PathLike, *, strict: bool = False) -> list[dict]:
    """Records of a ``results.jsonl`` file, in file order; a missing file gives ``[]``.

    A last line without newline, or a last line that is not valid JSON, is what a killed writer
    leaves: it is skipped with a warning naming file and line. A corrupt line elsewhere (not
    JSON) is skipped with a warning by default and raises ``ResultsFormatError`` (file and line)
    when ``strict``; a file with corrupt lines and no record at all (a binary or text file) is
    not a results file and always raises. A line that is JSON but not a valid record always
    raises ``ResultsFormatError`` naming file, line and field: another format or a version newer
    than :data:`RESULTS_VERSION`, a missing or unknown field, a value of the wrong type
    (``"seed": "abc"``, ``"success": "yes"``), a status not in :data:`STATUSES`, NaN, a key
    twice in one object, nesting deeper than :data:`~conceptfusion.strict_json.MAX_JSON_DEPTH`
    or an integer of more than :data:`~conceptfusion.strict_json.MAX_INT_DIGITS` digits. A path
    that is not a regular file (a folder, a FIFO, ``/dev/zero`` behind a symlink) or is larger
    than :data:`~conceptfusion.io_utils.MAX_RESULTS_BYTES` raises ``ResultsFormatError`` before
    anything is read.
    """
    p = Path(path)
    if not p.exists():
        return []
    records, _, corrupt, half_written, _ = _scan(_read(p), str(p))
    if corrupt and (strict or not records):
        no, why = corrupt[0]
        lead = f"{p}: line {no}: corrupt record: {why}"
        raise ResultsFormatError(lead if records else f"{lead}; no line holds a record: this is not a results file")
    for no, why in corrupt:
        warnings.warn(f"{p}: line {no}: skipping a corrupt record ({why})", stacklevel=2)
    if half_written:
        warnings.warn(half_written, stacklevel=2)
    return records


def repair_results(path: str | os.PathLike) -> int:
    """Make a results file safe to append to; returns the bytes removed.

    A half-written last line (what a killed writer leaves) is cut off in place (a truncate: it
    needs no free space, so a run stopped by a full disk repairs before space is freed). A missing
    or healthy file is left alone (returns 0). Any other damage is refused with
    ``ResultsFormatError`` naming the file and the line(s), and nothing is changed: a corrupt
    line elsewhere is not the signature of a killed writer but of something else writing to the
    file, so a resumed run neither appends after it (which would bury it in the middle of the
    run) nor drops it silently; fix or delete the line(s) named and resume again. Records that
    are JSON but invalid raise as in :func:`load_results`.
    """
    p = Path(path)
    if not p.exists():
        return 0
    data = _read(p)
    _, good_end, corrupt, _, _ = _scan(data, str(p))
    if corrupt:
        listed = "; ".join(f"line {no}: {why}" for no, why in corrupt[:3]) + ("; ..." if len(corrupt) > 3 else "")
        raise ResultsFormatError(f"{p}: holds {len(corrupt)} corrupt line(s) that a killed run does not leave "
                                 f"({listed}); not appending after them: fix or delete line(s) "
                                 f"{', '.join(str(no) for no, _ in corrupt)} and resume again")
    if good_end == len(data):
        return 0
    os.truncate(p, good_end)  # the first good_end bytes stay as they are
    return len(data) - good_end


def _outcome(record: dict) -> tuple:
    """What two records of one episode key must agree on to be the same result: status and metrics
    (not timings, finish time or the error's traceback text)."""
    return record.get("status"), json.dumps(record.get("metrics") or {}, sort_keys=True)


def _key_words(key: EpisodeKey) -> str:
    return f"{key.suite} {key.agent} [{key.encoder}] episode {key.episode_id} seed {key.seed}"


def _record_problems(path: Path, run_id: str):
    """Each problem of ``path`` for a run of ``run_id`` (see :func:`check_run_records`), in file order, as one line."""
    records, _, _, _, numbers = _scan(_read(path), str(path))
    first: dict[EpisodeKey, tuple[int, dict]] = {}
    for no, rec in zip(numbers, records):
        if rec["run_id"] != run_id:
            yield (f"{path}: line {no}: expected records of this folder's run {run_id!r} (its {RUN_CONFIG_FILE}), got a "
                   f"record of run {rec['run_id']!r}")
            continue
        key = record_key(rec)
        if key not in first:
            first[key] = (no, rec)
            continue
        no0, rec0 = first[key]
        if _outcome(rec0) != _outcome(rec):
            yield (f"{path}: lines {no0} and {no}: expected one outcome per episode, got two records of {_key_words(key)} "
                   f"that differ (status {rec0['status']} vs {rec['status']}, metrics {_outcome(rec0)[1]} vs "
                   f"{_outcome(rec)[1]})")


def check_run_records(path: str | os.PathLike, run_id: str) -> None:
    """Refuse a results file that a resumed run of ``run_id`` must not append to; a missing file passes.

    Every record must carry ``run_id`` (a record of another run was appended by something else:
    another run writing to the same folder, files concatenated), and two records of one
    :class:`EpisodeKey` (suite, agent and its options, encoder, episode, seed) must have the same
    outcome (status and metrics). Identical duplicates pass: they count once
    (:func:`latest_records`) and are left in the file.

    Raises:
        ResultsFormatError: naming the file, the line(s) and what differs; and as :func:`load_results`.
    """
    p = Path(path)
    if not p.exists():
        return
    for problem in _record_problems(p, run_id):
        fix = ("records of another run do not belong here: move them to their own folder and resume again"
               if "expected records of" in problem else "delete the wrong one and resume again")
        raise ResultsFormatError(f"{problem}; {fix}")


def warn_record_problems(folder: str | os.PathLike) -> None:
    """Warn (for ``report`` and ``compare``) about the records of a run folder that are not its
    run's or that disagree with another record of their episode (see :func:`check_run_records`),
    one warning each, naming file and line(s): the report counts the last record of each episode.
    A folder without a readable ``run.json`` is not checked."""
    folder = Path(folder)
    try:
        run_id = read_run_config(folder).get("run_id")
    except (OSError, ValueError):  # no or unreadable run.json: nothing to hold the records to
        return
    if not isinstance(run_id, str):
        return
    for problem in _record_problems(folder / RESULTS_FILE, run_id):
        warnings.warn(f"{problem}; the report counts the last record of each episode", stacklevel=3)


def load_runs(run_dirs) -> list[dict]:
    """Records of run folders (or results files), in order, for ``report`` and ``compare``.

    A run folder's record of another run than its ``run.json`` names, or one that disagrees with
    another record of its episode (see :func:`check_run_records`), is a warning naming the file
    and the line(s); the report counts the last record of each episode.

    Raises :class:`~conceptfusion.errors.MissingFileError` naming a path that does not exist
    or a folder that holds no :data:`RESULTS_FILE`, and ``ResultsFormatError`` as
    :func:`load_results` does or when there are no records at all.
    """
    paths = [run_dirs] if isinstance(run_dirs, (str, os.PathLike)) else list(run_dirs)
    if not paths:
        raise ResultsFormatError("expected at least one run folder, got none")
    records: list[dict] = []
    for item in paths:
        p = Path(item)
        results = p / RESULTS_FILE if p.is_dir() else p
        if not p.exists():
            raise MissingFileError(f"{p}: no such run folder or results file")
        if not results.exists():
            raise MissingFileError(f"{p}: no {RESULTS_FILE} here; is it a run folder?")
        records.extend(load_results(results))
        if p.is_dir():
            warn_record_problems(p)
    if not records:
        raise ResultsFormatError(f"no records in {', '.join(str(x) for x in paths)} (empty results file?)")
    return records


def completed_keys(records, *, statuses: tuple[str, ...] = STATUSES) -> set[EpisodeKey]:
    """Keys of the episodes already run, for resuming.

    By default every recorded status counts as done: a failed or timed-out episode is recorded
    as such and not retried (a deterministic agent would fail again). Pass
    ``statuses=("ok",)`` to retry them; :func:`latest_records` then keeps the newer record.
    """
    return {record_key(r) for r in records if r.get("status") in statuses}


def latest_records(records) -> list[dict]:
    """One record per :class:`EpisodeKey`, the last one in order (a retried episode's newest run)."""
    by_key: dict[EpisodeKey, dict] = {}
    for r in records:
        key = record_key(r)
        by_key.pop(key, None)
        by_key[key] = r
    return list(by_key.values())


def _normalise_config(config: dict) -> dict:
    if not isinstance(config, dict):
        raise TypeError(f"config: expected a dict, got {type(config).__name__}")
    try:
        return json.loads(json.dumps(config, sort_keys=True, allow_nan=False))
    except (TypeError, ValueError) as exc:
        raise TypeError(f"config: expected JSON-serialisable settings: {exc}") from exc


def read_run_config(run_dir: str | os.PathLike) -> dict:
    """The settings stored by :func:`write_run_config`; ``FileNotFoundError`` when there are none."""
    p = Path(run_dir) / RUN_CONFIG_FILE
    if not p.exists():
        raise FileNotFoundError(f"{p}: no run settings here; is {run_dir} a run folder?")
    try:
        doc = read_json_file(p, "run settings file", ResultsFormatError)
    except json.JSONDecodeError as exc:
        raise ResultsFormatError(f"{p}: corrupt run settings at line {exc.lineno}: {exc.msg}") from exc
    if not isinstance(doc, dict) or doc.get("format") != RUN_CONFIG_FORMAT:
        got = doc.get("format") if isinstance(doc, dict) else type(doc).__name__
        raise ResultsFormatError(f"{p}: not run settings: format {got!r}, expected {RUN_CONFIG_FORMAT!r}")
    version = doc.get("version")
    if not isinstance(version, int) or isinstance(version, bool) or not 1 <= version <= RUN_CONFIG_VERSION:
        raise ResultsFormatError(f"{p}: run settings version {version!r}; this code reads versions "
                                 f"1..{RUN_CONFIG_VERSION}")
    if not isinstance(doc.get("config"), dict):
        raise ResultsFormatError(f"{p}: expected a 'config' object, got {type(doc.get('config')).__name__}")
    return doc["config"]


def check_run_config(run_dir: str | os.PathLike, config: dict) -> None:
    """Raise ``ResultsFormatError`` listing the settings that differ from the stored ones."""
    stored, new = read_run_config(run_dir), _normalise_config(config)
    if stored == new:
        return
    diffs = [f"{k}: stored {stored.get(k, '<absent>')!r}, now {new.get(k, '<absent>')!r}"
             for k in sorted(set(stored) | set(new)) if stored.get(k, ...) != new.get(k, ...)]
    raise ResultsFormatError(f"{Path(run_dir) / RUN_CONFIG_FILE}: this run was started with other settings; "
                             f"{'; '.join(diffs)}")


def write_run_config(run_dir: str | os.PathLike, config: dict, *, overwrite: bool = False) -> Path:
    """Store a run's settings in ``run_dir/run.json`` (atomic, versioned); returns its path.

    When the file exists with different settings this raises ``ResultsFormatError`` (a resumed
    run must continue the same run) unless ``overwrite``. ``config`` must be JSON-serialisable.
    """
    norm = _normalise_config(config)
    p = Path(run_dir) / RUN_CONFIG_FILE
    if p.exists() and not overwrite:
        check_run_config(run_dir, norm)
    doc = {"format": RUN_CONFIG_FORMAT, "version": RUN_CONFIG_VERSION, "config": norm}
    return atomic_write_text(p, json.dumps(doc, indent=1, sort_keys=True) + "\n")
