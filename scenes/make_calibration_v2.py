"""Calibration data of the v2 agents (``scenes/calibration-v2/``): apartments, tables and episodes
to develop and choose agent settings (and perception) on, never to report.

- ``calibration-v2/household-v2-<seed>.json``: :data:`NUM_APARTMENTS` library apartments
  (:func:`~sim_envs.scenes.gen_household_v2.generate_household_v2`) on ``calibration`` seeds
  from index :data:`SEED_OFFSET` on (the tower's apartment score floor uses indices 100-111, the
  table floor 0-11), so they hold TRAIN and VAL instances, no TEST one;
- ``calibration-v2/search-episodes-v2.jsonl``: 6 object-search episodes per apartment, drawn as
  the shipped ``search-v2`` ones (goals named in turn by name, synonym, attribute, function),
  from another generator seed;
- ``calibration-v2/chain-episodes-v2.jsonl``: one multi-goal search (chains of 2, 3 and 4 goals
  in turn, :mod:`sim_envs.scenes.chain_episodes`) per apartment, and
  ``calibration-v2/fetch-episodes-v2.jsonl``: one "explore, then fetch" episode per apartment;
- ``calibration-v2/instruct-episodes-v2.jsonl``: the development instruction episodes
  (:func:`scenes.make_instruct_v2.dev_file`), 4 per apartment;
- ``calibration-v2/tabletop-v2-<seed>.json`` and ``calibration-v2/rearrange-episodes-v2.jsonl``:
  :data:`NUM_TABLE_EPISODES` rearrangement episodes drawn as the shipped ``rearrange-v2`` ones
  (:func:`~sim_envs.scenes.tabletop_v2_episodes.generate_tabletop_v2_episodes`, one table each,
  pushes checked against the PyBullet Panda's reach) on ``calibration`` seeds from index
  :data:`TABLE_SEED_OFFSET` on, so TRAIN and VAL instances only.

No suite runs them (their seeds are not evaluation seeds; ``tests/harness/test_suite_scenes.py``).

    python -m scenes.make_calibration_v2            # writes scenes/calibration-v2/
    python -m scenes.make_calibration_v2 --check    # exits 1 if the shipped files differ
"""

from __future__ import annotations

import sys

from scenes.shipped import generator_main
from sim_envs.scenes.chain_episodes import FETCH_EXPLORE_STEPS, FETCH_STEPS_PER_GOAL, chain_file_text
from sim_envs.scenes.search_episodes_v2 import search_episode_files
from sim_envs.scenes.splits import splits

__all__ = ["FOLDER", "SEARCH_FILE", "REARRANGE_FILE", "NUM_APARTMENTS", "SEED_OFFSET", "GENERATOR_SEED", "NUM_TABLE_EPISODES",
           "TABLE_SEED_OFFSET", "TABLE_GENERATOR_SEED", "CHAIN_FILE", "CHAIN_GENERATOR_SEED", "FETCH_FILE", "FETCH_GENERATOR_SEED", "chain_files", "apartment_seeds", "table_seeds", "search_files", "table_files", "build_files",
           "main"]

FOLDER = "calibration-v2"
"""Folder under ``scenes/`` of the v2 calibration data."""
SEARCH_FILE = f"{FOLDER}/search-episodes-v2.jsonl"
NUM_APARTMENTS = 30
SEED_OFFSET = 200
"""Index of the first apartment seed among the ``calibration`` seeds."""
GENERATOR_SEED = 7102
REARRANGE_FILE = f"{FOLDER}/rearrange-episodes-v2.jsonl"
NUM_TABLE_EPISODES = 80
TABLE_SEED_OFFSET = 300
"""Index of the first table seed among the ``calibration`` seeds (apartments above use 200-229)."""
TABLE_SEEDS = 1500
"""Calibration seeds the table episodes may draw from (a table with no reachable target is skipped)."""
TABLE_GENERATOR_SEED = 7103
CHAIN_FILE = f"{FOLDER}/chain-episodes-v2.jsonl"
CHAIN_GENERATOR_SEED = 7106
FETCH_FILE = f"{FOLDER}/fetch-episodes-v2.jsonl"
FETCH_GENERATOR_SEED = 7107


def apartment_seeds() -> list[int]:
    """Seeds of the calibration apartments: ``calibration`` seeds ``SEED_OFFSET ..`` ``SEED_OFFSET + NUM_APARTMENTS - 1``."""
    return splits().seeds_of("calibration", SEED_OFFSET + NUM_APARTMENTS)[SEED_OFFSET:]


def table_seeds() -> list[int]:
    """Seeds the calibration tables are drawn from: ``calibration`` seeds ``TABLE_SEED_OFFSET ..``
    ``TABLE_SEED_OFFSET + TABLE_SEEDS - 1``."""
    return splits().seeds_of("calibration", TABLE_SEED_OFFSET + TABLE_SEEDS)[TABLE_SEED_OFFSET:]


def table_files(count: int = NUM_TABLE_EPISODES) -> dict[str, str]:
    """Relative path under ``scenes/`` -> file text: the first ``count`` table episodes (the same
    first episodes whatever ``count``: the generator draws them in order) and their tables."""
    from scenes.make_tabletop_v2 import episode_files  # needs PyBullet (the Panda's reach)

    return episode_files(TABLE_GENERATOR_SEED, count, table_seeds(), folder=FOLDER, episode_file=REARRANGE_FILE,
                         id_prefix="rearrange-v2-cal")


def search_files() -> dict[str, str]:
    """Relative path under ``scenes/`` -> file text: every apartment and the search episode file."""
    return search_episode_files(apartment_seeds(), folder=FOLDER, episode_file=SEARCH_FILE, generator_seed=GENERATOR_SEED,
                                id_prefix="search-v2-cal")


def chain_files(search: dict[str, str]) -> dict[str, str]:
    """The chain episode file (``CHAIN_FILE`` -> text), one chain per apartment of ``search``
    (:func:`search_files`' output)."""
    apartments = {rel: text for rel, text in search.items() if rel.endswith(".json")}
    return {CHAIN_FILE: chain_file_text(apartments, per_scene=1, generator_seed=CHAIN_GENERATOR_SEED, id_prefix="chain-v2-cal"),
            FETCH_FILE: chain_file_text(apartments, per_scene=1, generator_seed=FETCH_GENERATOR_SEED, id_prefix="fetch-v2-cal",
                                        explore_steps=FETCH_EXPLORE_STEPS, steps_per_goal=FETCH_STEPS_PER_GOAL)}


def build_files() -> dict[str, str]:
    """Relative path under ``scenes/`` -> file text: every apartment and table, and the episode files."""
    from scenes.make_instruct_v2 import dev_file

    search = search_files()
    apartments = {rel: text for rel, text in search.items() if rel.endswith(".json")}
    return {**search, **chain_files(search), **table_files(), **dev_file(apartments)}


def main(argv: list[str] | None = None) -> int:
    return generator_main(build_files, FOLDER, __doc__.splitlines()[0], argv)


if __name__ == "__main__":
    sys.exit(main())
