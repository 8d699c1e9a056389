"""The ``oracle`` perception's score floor, read from the data file that records its derivation.

With ``oracle`` features every point of an object's segment carries the MiniLM text embedding of
the object's name, so a region's median score against a query is ``cos(embed(query),
embed(name))``. The floor must accept a goal's own wording and reject every other object of the
scene. It is not set by hand: ``python -m tower_training.oracle_floor --write`` derives it from
the floor-calibration scenes (``scenes/calibration/``) and writes :data:`ORACLE_FLOOR_FILE`;
``--check`` recomputes it and compares. This module only reads and validates that file.

File (JSON object, format :data:`ORACLE_FLOOR_FORMAT`, version :data:`ORACLE_FLOOR_VERSION`)::

    {"format": "cf-oracle-floor", "version": 1, "floor": F, "encoder": "minilm-text",
     "separated": true,             # every present score above every near-miss score
     "present":   {"pairs": P, "distinct_pairs": p, "min": S, "min_pair": [query, label], "rejected": 0},
     "near_miss": {"pairs": N, "distinct_pairs": n, "max": S, "max_pair": [query, label], "accepted": 0},
     "rule": "...", "wordings": {task: "..."}, "episode_files": [...], "scenes": [...], "command": "..."}
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from conceptfusion.errors import CalibrationFileError, MissingFileError
from conceptfusion.io_utils import read_text_file

__all__ = ["ORACLE_TEXT_ENCODER", "ORACLE_FLOOR_FILE", "ORACLE_FLOOR_FORMAT", "ORACLE_FLOOR_VERSION",
           "ORACLE_FLOOR_COMMAND", "read_oracle_floor_file", "load_oracle_floor"]

ORACLE_TEXT_ENCODER = "minilm-text"
"""The registry encoder whose text embeddings label the oracle's segments (and whose scores the
floor is derived from)."""

ORACLE_FLOOR_FILE = Path(__file__).resolve().parents[1] / "data" / "oracle_floor.json"
"""The shipped derivation of the ``oracle`` score floor."""
ORACLE_FLOOR_FORMAT = "cf-oracle-floor"
ORACLE_FLOOR_VERSION = 1
ORACLE_FLOOR_COMMAND = "python -m tower_training.oracle_floor --write"
"""The one command that writes :data:`ORACLE_FLOOR_FILE`."""


def _number(d: dict, key: str, where: str, path: Path) -> float:
    v = d.get(key)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or not -1.0 <= v <= 1.0:
        raise CalibrationFileError(f"{path}: {where}{key}: expected a cosine score in [-1, 1], got {v!r}")
    return float(v)


def _count(d: dict, key: str, where: str, path: Path, *, positive: bool = False) -> int:
    v = d.get(key)
    if isinstance(v, bool) or not isinstance(v, int) or v < (1 if positive else 0):
        raise CalibrationFileError(f"{path}: {where}{key}: expected an int >= {1 if positive else 0}, got {v!r}")
    return v


def _section(d: dict, key: str, path: Path) -> dict:
    v = d.get(key)
    if not isinstance(v, dict):
        raise CalibrationFileError(f"{path}: {key}: expected an object, got {type(v).__name__}")
    return v


def read_oracle_floor_file(path: str | Path = ORACLE_FLOOR_FILE) -> dict:
    """The validated content of an oracle floor file (see the module docstring).

    Raises:
        MissingFileError: no file at ``path`` (the message names the command that writes it).
        CalibrationFileError: not JSON, another format or version, a missing or invalid field, or
            a floor that does not lie between the highest near-miss and the lowest present score
            although the file says they separate.
    """
    p = Path(path)
    try:
        text = read_text_file(p, "oracle score floor file", CalibrationFileError)
    except MissingFileError as exc:
        raise MissingFileError(f"{exc} (write it with {ORACLE_FLOOR_COMMAND})") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise CalibrationFileError(f"{p}: not an oracle score floor file: invalid JSON ({exc})") from None
    if not isinstance(data, dict):
        raise CalibrationFileError(f"{p}: expected a JSON object (format {ORACLE_FLOOR_FORMAT!r}), got {type(data).__name__}")
    if data.get("format") != ORACLE_FLOOR_FORMAT or data.get("version") != ORACLE_FLOOR_VERSION:
        raise CalibrationFileError(f"{p}: expected format {ORACLE_FLOOR_FORMAT!r} version {ORACLE_FLOOR_VERSION}, "
                                   f"got format {data.get('format')!r} version {data.get('version')!r} "
                                   f"(rewrite it with {ORACLE_FLOOR_COMMAND})")
    floor = _number(data, "floor", "", p)
    if data.get("encoder") != ORACLE_TEXT_ENCODER:
        raise CalibrationFileError(f"{p}: encoder: expected {ORACLE_TEXT_ENCODER!r} (the oracle's text encoder), "
                                   f"got {data.get('encoder')!r}")
    if not isinstance(data.get("separated"), bool):
        raise CalibrationFileError(f"{p}: separated: expected true or false, got {data.get('separated')!r}")
    present, near = _section(data, "present", p), _section(data, "near_miss", p)
    _count(present, "pairs", "present.", p, positive=True)
    _count(near, "pairs", "near_miss.", p, positive=True)
    lo, hi = _number(present, "min", "present.", p), _number(near, "max", "near_miss.", p)
    rejected, accepted = _count(present, "rejected", "present.", p), _count(near, "accepted", "near_miss.", p)
    scenes = data.get("scenes")
    if not isinstance(scenes, list) or not scenes or not all(isinstance(s, str) and s for s in scenes):
        raise CalibrationFileError(f"{p}: scenes: expected a non-empty list of scene paths, got {scenes!r}")
    if data["separated"] and not (hi < floor <= lo and rejected == 0 and accepted == 0):
        raise CalibrationFileError(f"{p}: floor {floor} does not separate the near-miss maximum {hi} from the present "
                                   f"minimum {lo} (rejected {rejected}, accepted {accepted}) although 'separated' is true")
    return data


def load_oracle_floor(path: str | Path = ORACLE_FLOOR_FILE) -> float:
    """The ``oracle`` score floor recorded in ``path`` (raises what :func:`read_oracle_floor_file` raises)."""
    return float(read_oracle_floor_file(path)["floor"])
