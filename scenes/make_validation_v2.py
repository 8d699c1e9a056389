"""Validation data of the v2 agents (``scenes/validation-v2/``): open-world rearrangement episodes
to develop agent settings on, never to report.

The calibration episodes (:mod:`scenes.make_calibration_v2`) hold TRAIN instances only, so an
agent setting chosen there is chosen on objects the tower was trained on; the evaluation episodes
also name held-out instances and held-out categories. These episodes fill that gap without
touching the test split: their tables are drawn on ``tower_val`` seeds (TRAIN and VAL instances;
from index :data:`TABLE_SEED_OFFSET` on, past the tower's own validation arrangements) and every
target is a VAL instance (:func:`~sim_envs.scenes.splits.object_group` ``"validation"``: a
held-out instance of a trained category or an instance of a validation category), named by name,
synonym, attribute or function as the shipped ``rearrange-v2`` goals, pushes checked against the
PyBullet Panda's reach.

- ``validation-v2/tabletop-v2-<seed>.json``: the tables;
- ``validation-v2/rearrange-episodes-v2.jsonl``: :data:`NUM_TABLE_EPISODES` episodes.

No suite runs them (their seeds are not evaluation seeds; ``tests/harness/test_suite_scenes.py``).

    python -m scenes.make_validation_v2            # writes scenes/validation-v2/
    python -m scenes.make_validation_v2 --check    # exits 1 if the shipped files differ
"""

from __future__ import annotations

import sys

from scenes.shipped import generator_main
from sim_envs.scenes.splits import splits

__all__ = ["FOLDER", "REARRANGE_FILE", "NUM_TABLE_EPISODES", "TABLE_SEED_OFFSET", "TABLE_SEEDS", "TABLE_GENERATOR_SEED",
           "GOAL_GROUPS", "table_seeds", "table_files", "build_files", "main"]

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
GOAL_GROUPS = ("validation",)
"""Split groups a target may come from."""


def table_seeds() -> list[int]:
    """Seeds the validation tables are drawn from: ``tower_val`` seeds ``TABLE_SEED_OFFSET ..``
    ``TABLE_SEED_OFFSET + TABLE_SEEDS - 1``."""
    return splits().seeds_of("tower_val", TABLE_SEED_OFFSET + TABLE_SEEDS)[TABLE_SEED_OFFSET:]


def table_files(count: int = NUM_TABLE_EPISODES) -> dict[str, str]:
    """Relative path under ``scenes/`` -> file text: the first ``count`` episodes (the same first
    episodes whatever ``count``) and their tables."""
    from scenes.make_tabletop_v2 import episode_files  # needs PyBullet (the Panda's reach)

    return episode_files(TABLE_GENERATOR_SEED, count, table_seeds(), folder=FOLDER, episode_file=REARRANGE_FILE,
                         id_prefix="rearrange-v2-val", goal_groups=GOAL_GROUPS)


def build_files() -> dict[str, str]:
    """Relative path under ``scenes/`` -> file text: every table and the episode file."""
    return table_files()


def main(argv: list[str] | None = None) -> int:
    return generator_main(build_files, FOLDER, __doc__.splitlines()[0], argv)


if __name__ == "__main__":
    sys.exit(main())
