"""The sealed test set of the v2 agents (``scenes/sealed-v2/``): the episodes headline figures are
measured on, once, after every choice is frozen.

Drawn on the split file's ``sealed`` seeds, which no decision has touched (no tower, floor, agent
setting or suite setting was chosen on them): their apartments and tables hold TRAIN and TEST
instances only (no validation instance, not even as a distractor), and every goal is a seen
instance, a held-out instance of a trained category or an instance of a held-out category
(:data:`GOAL_GROUPS`). Goals are named in turn by name, synonym, attribute and function as the
``search-v2`` and ``rearrange-v2`` ones; pushes are checked against the PyBullet Panda's reach.

- ``sealed-v2/household-v2-<seed>.json``: :data:`NUM_APARTMENTS` apartments;
- ``sealed-v2/search-episodes-v2.jsonl``: 6 object-search episodes per apartment (150);
- ``sealed-v2/tabletop-v2-<seed>.json`` and ``sealed-v2/rearrange-episodes-v2.jsonl``:
  :data:`NUM_TABLE_EPISODES` rearrangement episodes, one table each;
- ``sealed-v2/chain-episodes-v2.jsonl``: :data:`NUM_CHAINS` multi-goal searches (chains of 2, 3
  and 4 goals in turn, :mod:`sim_envs.scenes.chain_episodes`) in the first apartments, two each;
- ``sealed-v2/fetch-episodes-v2.jsonl``: :data:`NUM_FETCH` "explore, then fetch" episodes (an
  exploration budget, then 2, 3 or 4 goals one at a time) in the other apartments, three each.

Sizes: a success rate near one half over 150 episodes has a 95% interval of about +-0.08 (Wilson).
``sealed-v2/MANIFEST.json`` records every file's and every episode's SHA-256
(:mod:`sim_envs.scenes.sealed`); suites refuse a sealed file that does not match it, and every
development command refuses to read one.

    python -m scenes.make_sealed_v2            # writes scenes/sealed-v2/ and its manifest
    python -m scenes.make_sealed_v2 --check    # exits 1 if the shipped files differ
"""

from __future__ import annotations

import sys

from scenes.shipped import generator_main
from sim_envs.scenes.chain_episodes import FETCH_EXPLORE_STEPS, FETCH_STEPS_PER_GOAL, chain_file_text
from sim_envs.scenes.sealed import MANIFEST_NAME, SEALED_FOLDER_NAME, manifest_text
from sim_envs.scenes.search_episodes_v2 import search_episode_files
from sim_envs.scenes.splits import splits

__all__ = ["FOLDER", "SEARCH_FILE", "REARRANGE_FILE", "CHAIN_FILE", "NUM_CHAINS", "chain_file", "FETCH_FILE", "NUM_FETCH", "fetch_file", "NUM_APARTMENTS", "NUM_TABLE_EPISODES", "TABLE_SEED_OFFSET", "TABLE_SEEDS",
           "SEARCH_GENERATOR_SEED", "TABLE_GENERATOR_SEED", "GOAL_GROUPS", "apartment_seeds", "table_seeds", "build_files", "main"]

FOLDER = SEALED_FOLDER_NAME
"""Folder under ``scenes/`` of the sealed set."""
SEARCH_FILE = f"{FOLDER}/search-episodes-v2.jsonl"
REARRANGE_FILE = f"{FOLDER}/rearrange-episodes-v2.jsonl"
NUM_APARTMENTS = 25
NUM_TABLE_EPISODES = 160
TABLE_SEED_OFFSET = 1000
"""Index of the first table seed among the ``sealed`` seeds (apartments use the first 25)."""
TABLE_SEEDS = 3000
"""``sealed`` seeds the table episodes may draw from (a table with no reachable target is skipped)."""
SEARCH_GENERATOR_SEED = 9401
TABLE_GENERATOR_SEED = 9402
CHAIN_FILE = f"{FOLDER}/chain-episodes-v2.jsonl"
NUM_CHAINS = 30
CHAIN_GENERATOR_SEED = 9403
FETCH_FILE = f"{FOLDER}/fetch-episodes-v2.jsonl"
NUM_FETCH = 30
FETCH_GENERATOR_SEED = 9404
GOAL_GROUPS = ("seen", "held_out_instance", "held_out_category")
"""Split groups a goal may come from: every group but ``validation``."""


def apartment_seeds() -> list[int]:
    """The first :data:`NUM_APARTMENTS` ``sealed`` seeds."""
    return splits().seeds_of("sealed", NUM_APARTMENTS)


def table_seeds() -> list[int]:
    """``sealed`` seeds ``TABLE_SEED_OFFSET ..`` ``TABLE_SEED_OFFSET + TABLE_SEEDS - 1``."""
    return splits().seeds_of("sealed", TABLE_SEED_OFFSET + TABLE_SEEDS)[TABLE_SEED_OFFSET:]


def build_files() -> dict[str, str]:
    """Relative path under ``scenes/`` -> file text: every apartment and table, both episode files
    and the manifest of their hashes."""
    from scenes.make_tabletop_v2 import episode_files  # needs PyBullet (the Panda's reach)

    files = search_episode_files(apartment_seeds(), folder=FOLDER, episode_file=SEARCH_FILE, generator_seed=SEARCH_GENERATOR_SEED,
                                 id_prefix="search-v2-sealed", goal_groups=GOAL_GROUPS)
    files.update(episode_files(TABLE_GENERATOR_SEED, NUM_TABLE_EPISODES, table_seeds(), folder=FOLDER, episode_file=REARRANGE_FILE,
                               id_prefix="rearrange-v2-sealed", goal_groups=GOAL_GROUPS))
    files[CHAIN_FILE] = chain_file(files)
    files[FETCH_FILE] = fetch_file(files)
    files[f"{FOLDER}/{MANIFEST_NAME}"] = manifest_text(files, episode_files=(SEARCH_FILE, REARRANGE_FILE, CHAIN_FILE, FETCH_FILE))
    return files


def chain_file(files: dict[str, str]) -> str:
    """The chain episode file's text, drawn in the first ``NUM_CHAINS // 2`` apartments of ``files``, two each."""
    apartments = {f"{FOLDER}/household-v2-{seed}.json": files[f"{FOLDER}/household-v2-{seed}.json"]
                  for seed in apartment_seeds()[: NUM_CHAINS // 2]}
    text = chain_file_text(apartments, per_scene=2, generator_seed=CHAIN_GENERATOR_SEED, id_prefix="chain-v2-sealed",
                           goal_groups=GOAL_GROUPS)
    drawn = text.count("\n") - 1
    if drawn != NUM_CHAINS:
        raise RuntimeError(f"expected {NUM_CHAINS} chains, the generator drew {drawn}")
    return text


def fetch_file(files: dict[str, str]) -> str:
    """The "explore, then fetch" episode file's text, drawn in the apartments the chains leave, three each."""
    apartments = {f"{FOLDER}/household-v2-{seed}.json": files[f"{FOLDER}/household-v2-{seed}.json"]
                  for seed in apartment_seeds()[NUM_CHAINS // 2:]}
    text = chain_file_text(apartments, per_scene=NUM_FETCH // len(apartments), generator_seed=FETCH_GENERATOR_SEED,
                           id_prefix="fetch-v2-sealed", goal_groups=GOAL_GROUPS, explore_steps=FETCH_EXPLORE_STEPS,
                           steps_per_goal=FETCH_STEPS_PER_GOAL)
    drawn = text.count("\n") - 1
    if drawn != NUM_FETCH:
        raise RuntimeError(f"expected {NUM_FETCH} fetch episodes, the generator drew {drawn}")
    return text


def main(argv: list[str] | None = None) -> int:
    return generator_main(build_files, FOLDER, __doc__.splitlines()[0], argv)


if __name__ == "__main__":
    sys.exit(main())
