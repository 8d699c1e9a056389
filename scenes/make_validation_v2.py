"""Validation data of the v2 agents (``scenes/validation-v2/``): open-world rearrangement and
search episodes to develop agent settings on, never to report.

The calibration episodes (:mod:`scenes.make_calibration_v2`) hold TRAIN instances only, so an
agent setting chosen there is chosen on objects the tower was trained on; the evaluation episodes
also name held-out instances and held-out categories. These episodes fill that gap without
touching the test split: their tables and apartments are drawn on ``tower_val`` seeds (TRAIN and
VAL instances; tables from index :data:`TABLE_SEED_OFFSET` on, apartments from
:data:`APARTMENT_SEED_OFFSET`, past the tower's own validation arrangements) and every target or
goal is a VAL instance (:func:`~sim_envs.scenes.splits.object_group` ``"validation"``: a held-out
instance of a trained category or an instance of a validation category), named by name, synonym,
attribute or function as the shipped ``rearrange-v2`` and ``search-v2`` goals; pushes are checked
against the PyBullet Panda's reach.

- ``validation-v2/tabletop-v2-<seed>.json``: the tables;
- ``validation-v2/rearrange-episodes-v2.jsonl``: :data:`NUM_TABLE_EPISODES` episodes;
- ``validation-v2/household-v2-<seed>.json``: :data:`NUM_APARTMENTS` apartments;
- ``validation-v2/search-episodes-v2.jsonl``: up to 6 object-search episodes per apartment, drawn
  as the ``search-v2`` ones among the apartment's VAL instances.

No suite runs them (their seeds are not evaluation seeds; ``tests/harness/test_suite_scenes.py``).

    python -m scenes.make_validation_v2            # writes scenes/validation-v2/
    python -m scenes.make_validation_v2 --check    # exits 1 if the shipped files differ
"""

from __future__ import annotations

import sys

from scenes.shipped import generator_main
from sim_envs.scenes.search_episodes_v2 import search_episode_files
from sim_envs.scenes.splits import splits

__all__ = ["FOLDER", "REARRANGE_FILE", "SEARCH_FILE", "NUM_TABLE_EPISODES", "TABLE_SEED_OFFSET", "TABLE_SEEDS",
           "TABLE_GENERATOR_SEED", "NUM_APARTMENTS", "APARTMENT_SEED_OFFSET", "SEARCH_GENERATOR_SEED", "GOAL_GROUPS",
           "table_seeds", "apartment_seeds", "table_files", "search_files", "build_files", "main"]

FOLDER = "validation-v2"
"""Folder under ``scenes/`` of the v2 validation data."""
REARRANGE_FILE = f"{FOLDER}/rearrange-episodes-v2.jsonl"
NUM_TABLE_EPISODES = 80
TABLE_SEED_OFFSET = 1000
"""Index of the first table seed among the ``tower_val`` seeds (the tower's validation
arrangements use the first 60)."""
TABLE_SEEDS = 3000
"""``tower_val`` seeds the table episodes may draw from (a table with no reachable VAL target is skipped)."""
TABLE_GENERATOR_SEED = 7104
SEARCH_FILE = f"{FOLDER}/search-episodes-v2.jsonl"
NUM_APARTMENTS = 15
APARTMENT_SEED_OFFSET = 500
"""Index of the first apartment seed among the ``tower_val`` seeds."""
SEARCH_GENERATOR_SEED = 7105
GOAL_GROUPS = ("validation",)
"""Split groups a target or goal may come from."""


def table_seeds() -> list[int]:
    """Seeds the validation tables are drawn from: ``tower_val`` seeds ``TABLE_SEED_OFFSET ..``
    ``TABLE_SEED_OFFSET + TABLE_SEEDS - 1``."""
    return splits().seeds_of("tower_val", TABLE_SEED_OFFSET + TABLE_SEEDS)[TABLE_SEED_OFFSET:]


def apartment_seeds() -> list[int]:
    """Seeds of the validation apartments: ``tower_val`` seeds ``APARTMENT_SEED_OFFSET ..``
    ``APARTMENT_SEED_OFFSET + NUM_APARTMENTS - 1``."""
    return splits().seeds_of("tower_val", APARTMENT_SEED_OFFSET + NUM_APARTMENTS)[APARTMENT_SEED_OFFSET:]


def search_files() -> dict[str, str]:
    """Relative path under ``scenes/`` -> file text: every apartment and the search episode file."""
    return search_episode_files(apartment_seeds(), folder=FOLDER, episode_file=SEARCH_FILE, generator_seed=SEARCH_GENERATOR_SEED,
                                id_prefix="search-v2-val", goal_groups=GOAL_GROUPS)


def table_files(count: int = NUM_TABLE_EPISODES) -> dict[str, str]:
    """Relative path under ``scenes/`` -> file text: the first ``count`` episodes (the same first
    episodes whatever ``count``) and their tables."""
    from scenes.make_tabletop_v2 import episode_files  # needs PyBullet (the Panda's reach)

    return episode_files(TABLE_GENERATOR_SEED, count, table_seeds(), folder=FOLDER, episode_file=REARRANGE_FILE,
                         id_prefix="rearrange-v2-val", goal_groups=GOAL_GROUPS)


def build_files() -> dict[str, str]:
    """Relative path under ``scenes/`` -> file text: every table and apartment, and both episode files."""
    return {**table_files(), **search_files()}


def main(argv: list[str] | None = None) -> int:
    return generator_main(build_files, FOLDER, __doc__.splitlines()[0], argv)


if __name__ == "__main__":
    sys.exit(main())
