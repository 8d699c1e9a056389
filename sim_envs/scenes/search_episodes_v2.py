"""The shipped household v2 data: 20 apartments on evaluation seeds and 120 object-search episodes.

    python -m sim_envs.scenes.search_episodes_v2            # (re)writes scenes/household-v2/
    python -m sim_envs.scenes.search_episodes_v2 --check    # exit 1 if the shipped files differ

Apartments come from :func:`~sim_envs.scenes.gen_household_v2.generate_household_v2` on the first
:data:`NUM_APARTMENTS` seeds of the split file's ``evaluation`` range; episodes from
:func:`~sim_envs.scenes.search_episodes.generate_search_episodes`, 6 per apartment, goals named
in turn by name, synonym, attribute and function (``description_kind`` per episode).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path
from typing import Sequence

from conceptfusion.io_utils import atomic_write_text
from sim_envs.scenes.episodes import SCENES_ROOT, EpisodeSet, episodes_text, load_episodes
from sim_envs.scenes.gen_household_v2 import generate_household_v2
from sim_envs.scenes.search_episodes import generate_search_episodes
from sim_envs.scenes.splits import splits

__all__ = ["V2_DIR", "V2_SEARCH_FILE", "NUM_APARTMENTS", "PER_SCENE", "V2_DESCRIPTION_KINDS", "apartment_seeds",
           "v2_search_episodes", "search_episode_files", "main"]

V2_DIR = SCENES_ROOT / "household-v2"
"""Folder of the shipped v2 apartments and episodes."""
V2_SEARCH_FILE = V2_DIR / "episodes-v2.jsonl"
"""The shipped v2 object-search episodes."""
NUM_APARTMENTS = 20
PER_SCENE = 6
V2_DESCRIPTION_KINDS = ("name", "synonym", "attribute", "function")
"""How v2 goals are named, in turn."""
_GENERATOR_SEED = 2


def apartment_seeds() -> list[int]:
    """Seeds of the shipped v2 apartments: the first :data:`NUM_APARTMENTS` evaluation seeds."""
    return splits().seeds_of("evaluation", NUM_APARTMENTS)


def v2_search_episodes() -> EpisodeSet:
    """The shipped v2 object-search episodes (``scenes/household-v2/episodes-v2.jsonl``)."""
    return load_episodes(V2_SEARCH_FILE)


def search_episode_files(seeds: Sequence[int], *, folder: str, episode_file: str, generator_seed: int, id_prefix: str,
                         goal_groups: tuple[str, ...] | None = None) -> dict[str, str]:
    """Relative path under ``scenes/`` -> file text: an apartment per seed
    (``<folder>/<scene id>.json``) and :data:`PER_SCENE` search episodes per apartment drawn as the
    shipped v2 ones (``episode_file``; goals from ``goal_groups`` only when given)."""
    files = {}
    with tempfile.TemporaryDirectory() as tmp:  # the episode generator reads scene files
        root = Path(tmp)
        (root / folder).mkdir()
        paths = []
        for seed in seeds:
            scene = generate_household_v2(seed)
            rel = f"{folder}/{scene.id}.json"
            files[rel] = json.dumps(scene.to_json(), indent=1)
            (root / rel).write_text(files[rel])
            paths.append(root / rel)
        eps = generate_search_episodes(paths, per_scene=PER_SCENE, generator_seed=generator_seed, scenes_root=root,
                                       description_kinds=V2_DESCRIPTION_KINDS, id_prefix=id_prefix, goal_groups=goal_groups)
    files[episode_file] = episodes_text(eps)
    return files


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m sim_envs.scenes.search_episodes_v2", description=__doc__.splitlines()[0])
    p.add_argument("--check", action="store_true", help="compare with the shipped files instead of writing them")
    args = p.parse_args(argv)
    files = search_episode_files(apartment_seeds(), folder=V2_DIR.name, episode_file=f"{V2_DIR.name}/{V2_SEARCH_FILE.name}",
                                 generator_seed=_GENERATOR_SEED, id_prefix="search-v2")
    episodes = files[f"{V2_DIR.name}/{V2_SEARCH_FILE.name}"].count("\n") - 1  # a header line, then one per episode
    counts = f"{len(files) - 1} apartments and {episodes} episodes"
    if args.check:
        bad = [rel for rel, text in files.items() if not (SCENES_ROOT / rel).is_file() or (SCENES_ROOT / rel).read_text() != text]
        extra = sorted(f"{V2_DIR.name}/{f.name}" for f in V2_DIR.glob("household-v2-*.json") if f"{V2_DIR.name}/{f.name}" not in files)
        if bad or extra:
            print(f"{V2_DIR}: differs from the generators: {', '.join(bad + extra)}")
            return 1
        print(f"{V2_DIR}: {counts} match the generators")
        return 0
    V2_DIR.mkdir(parents=True, exist_ok=True)
    for rel in sorted(files):
        atomic_write_text(SCENES_ROOT / rel, files[rel])
    print(f"wrote {counts} to {V2_DIR}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
