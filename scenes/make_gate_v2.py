"""Episodes of the v2 regression gate (``scenes/gate-v2/``): the pinned episodes the
``regression-rearrange-v2`` and ``regression-search-v2`` suites run in CI, and the calibration
episodes their success bounds are derived from (:mod:`harness.runner.bounds`).

Both halves are drawn like the headline's sealed episodes, with development objects in the place
of test ones: tables and apartments on ``tower_val`` seeds no other file uses (indices from
:data:`APARTMENT_OFFSET` and :data:`TABLE_OFFSET` on; the tower's validation arrangements use the
first 60, ``validation-v2`` indices 500-3999), which hold TRAIN and VAL instances, and goals that
are seen instances or VAL instances (:data:`GOAL_GROUPS`). So, as on the sealed set, some goals
are objects the tower never trained on, where the score floor rejects them and the agents'
``identify`` and presume rules decide; and the gate never reads a test instance. Pinned and
calibration episodes share no apartment and no table; goals are named by name, synonym, attribute
and function in turn, pushes checked against the PyBullet Panda's reach.

- ``gate-v2/search-episodes-v2.jsonl``: 6 searches in each of :data:`PINNED_APARTMENTS`
  apartments, written round-robin (the first episode of every apartment, then the second, ...)
  so that the first ``n`` a suite pins spread over as many apartments as they can;
- ``gate-v2/search-calibration-v2.jsonl``: 6 searches in each of :data:`CALIBRATION_APARTMENTS`
  other apartments;
- ``gate-v2/rearrange-episodes-v2.jsonl`` and ``gate-v2/rearrange-calibration-v2.jsonl``:
  :data:`PINNED_TABLES` and :data:`CALIBRATION_TABLES` rearrangement episodes, one table each;
- ``gate-v2/household-v2-<seed>.json`` and ``gate-v2/tabletop-v2-<seed>.json``: their scenes.

    python -m scenes.make_gate_v2            # writes scenes/gate-v2/
    python -m scenes.make_gate_v2 --check    # exits 1 if the shipped files differ
"""

from __future__ import annotations

import json
import sys

from scenes.shipped import generator_main
from sim_envs.scenes.search_episodes_v2 import search_episode_files
from sim_envs.scenes.splits import splits

__all__ = ["FOLDER", "SEARCH_FILE", "SEARCH_CALIBRATION_FILE", "REARRANGE_FILE", "REARRANGE_CALIBRATION_FILE",
           "SEED_ROLE", "GOAL_GROUPS", "PINNED_APARTMENTS", "CALIBRATION_APARTMENTS", "PINNED_TABLES", "CALIBRATION_TABLES", "APARTMENT_OFFSET",
           "TABLE_OFFSET", "TABLE_POOL", "apartment_seeds", "table_seeds", "round_robin", "search_files", "table_files",
           "build_files", "main"]

FOLDER = "gate-v2"
"""Folder under ``scenes/`` of the gate's episodes."""
SEARCH_FILE = f"{FOLDER}/search-episodes-v2.jsonl"
SEARCH_CALIBRATION_FILE = f"{FOLDER}/search-calibration-v2.jsonl"
REARRANGE_FILE = f"{FOLDER}/rearrange-episodes-v2.jsonl"
REARRANGE_CALIBRATION_FILE = f"{FOLDER}/rearrange-calibration-v2.jsonl"
PINNED_APARTMENTS = 12
CALIBRATION_APARTMENTS = 20
PINNED_TABLES = 80
CALIBRATION_TABLES = 120
SEED_ROLE = "tower_val"
"""Seed role of the gate's scenes (TRAIN and VAL instances)."""
GOAL_GROUPS = ("seen", "validation")
"""Split groups a goal may come from (:func:`~sim_envs.scenes.splits.object_group`)."""
APARTMENT_OFFSET = 5000
"""Index of the first gate apartment among the ``tower_val`` seeds (pinned first, then calibration)."""
TABLE_OFFSET = 6000
"""Index of the first table seed among the ``tower_val`` seeds: the pinned tables draw from
:data:`TABLE_POOL` seeds from here, the calibration tables from the next :data:`TABLE_POOL`."""
TABLE_POOL = 1500
"""Seeds each half's tables may draw from (a table with no reachable target is skipped)."""
SEARCH_GENERATOR_SEEDS = (8101, 8102)
TABLE_GENERATOR_SEEDS = (8103, 8104)


def apartment_seeds(half: str) -> list[int]:
    """``tower_val`` seeds of the ``"pinned"`` or ``"calibration"`` apartments."""
    seeds = splits().seeds_of(SEED_ROLE, APARTMENT_OFFSET + PINNED_APARTMENTS + CALIBRATION_APARTMENTS)[APARTMENT_OFFSET:]
    return seeds[:PINNED_APARTMENTS] if _half(half) == 0 else seeds[PINNED_APARTMENTS:]


def table_seeds(half: str) -> list[int]:
    """``tower_val`` seeds the ``"pinned"`` or ``"calibration"`` tables draw from."""
    lo = TABLE_OFFSET + _half(half) * TABLE_POOL
    return splits().seeds_of(SEED_ROLE, lo + TABLE_POOL)[lo:]


def _half(half: str) -> int:
    if half not in ("pinned", "calibration"):
        raise ValueError(f"half: expected 'pinned' or 'calibration', got {half!r}")
    return 0 if half == "pinned" else 1


def round_robin(text: str) -> str:
    """An episode file's text with its episodes reordered: the first episode of each scene (in
    the order scenes first appear), then the second of each, and so on."""
    header, *lines = text.splitlines()
    by_scene: dict[str, list[str]] = {}
    for line in lines:
        by_scene.setdefault(json.loads(line)["scene"], []).append(line)
    queues = list(by_scene.values())
    out = [header]
    for i in range(max(map(len, queues), default=0)):
        out += [q[i] for q in queues if i < len(q)]
    return "\n".join(out) + "\n"


def search_files() -> dict[str, str]:
    """Relative path under ``scenes/`` -> file text: both halves' apartments and search episodes."""
    files = {}
    for half, episode_file, seed, tag in (("pinned", SEARCH_FILE, SEARCH_GENERATOR_SEEDS[0], "pin"),
                                          ("calibration", SEARCH_CALIBRATION_FILE, SEARCH_GENERATOR_SEEDS[1], "cal")):
        files.update(search_episode_files(apartment_seeds(half), folder=FOLDER, episode_file=episode_file,
                                          generator_seed=seed, id_prefix=f"search-v2-gate-{tag}",
                                          goal_groups=GOAL_GROUPS))
    files[SEARCH_FILE] = round_robin(files[SEARCH_FILE])
    return files


def table_files(pinned: int = PINNED_TABLES, calibration: int = CALIBRATION_TABLES) -> dict[str, str]:
    """Relative path under ``scenes/`` -> file text: the first ``pinned`` and ``calibration``
    table episodes of each half (the same first episodes whatever the counts) and their tables."""
    from scenes.make_tabletop_v2 import episode_files  # needs PyBullet (the Panda's reach)

    files = {}
    for half, count, episode_file, seed, tag in (("pinned", pinned, REARRANGE_FILE, TABLE_GENERATOR_SEEDS[0], "pin"),
                                                 ("calibration", calibration, REARRANGE_CALIBRATION_FILE,
                                                  TABLE_GENERATOR_SEEDS[1], "cal")):
        if count:
            files.update(episode_files(seed, count, table_seeds(half), folder=FOLDER, episode_file=episode_file,
                                       id_prefix=f"rearrange-v2-gate-{tag}", goal_groups=GOAL_GROUPS))
    return files


def build_files() -> dict[str, str]:
    """Relative path under ``scenes/`` -> file text: every apartment and table and the four episode files."""
    return {**search_files(), **table_files()}


def main(argv: list[str] | None = None) -> int:
    return generator_main(build_files, FOLDER, __doc__.splitlines()[0], argv)


if __name__ == "__main__":
    sys.exit(main())
