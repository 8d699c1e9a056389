"""File names shared by the episode replays and the reports that link them.

An episode's files live in ``RUN/replays/`` under one stem (:func:`replay_stem`): its recording
``<stem>.npz``, its video ``<stem>.mp4`` (or ``.gif``) and a map agent's final map
``<stem>.map.npz`` (a :mod:`conceptfusion.map.persistence` file).
"""

from __future__ import annotations

import re
from collections.abc import Mapping

__all__ = ["REPLAYS_DIR", "MAP_SUFFIX", "VIDEO_SUFFIXES", "replay_stem"]

REPLAYS_DIR = "replays"
"""Folder inside a run folder that holds recordings, replay videos and maps."""
MAP_SUFFIX = ".map.npz"
"""File name ending of an episode's final map (``<stem>.map.npz``)."""
VIDEO_SUFFIXES = (".mp4", ".gif")
"""Replay video endings, preferred first."""

_UNSAFE = re.compile(r"[^A-Za-z0-9._-]+")


def _part(value) -> str:
    return _UNSAFE.sub("-", str(value)).strip("-.") or "x"


def replay_stem(record: Mapping) -> str:
    """``<suite>__<agent>__<episode_id>__s<seed>`` for a results record, each part reduced to
    ``[A-Za-z0-9._-]`` (runs of other characters become one ``-``).

    A record without one of ``suite``, ``agent``, ``episode_id``, ``seed`` raises ``ValueError``
    naming the missing keys.
    """
    if not isinstance(record, Mapping):
        raise TypeError(f"replay_stem: expected a results record (dict), got {type(record).__name__}")
    missing = [k for k in ("suite", "agent", "episode_id", "seed") if k not in record]
    if missing:
        raise ValueError(f"replay_stem: the record lacks {', '.join(missing)} (has {', '.join(sorted(map(str, record)))})")
    return "__".join([_part(record["suite"]), _part(record["agent"]), _part(record["episode_id"]),
                      "s" + _part(record["seed"])])
