"""Regenerate the calibration episodes of the regression bounds (``scenes/calibration/``).

The regression suites pin the first episodes of the shipped files (``tabletop/episodes-v1.jsonl``,
``household/episodes-v1.jsonl``); their bounds are derived (:mod:`harness.runner.bounds`) from
runs over *other* episodes drawn from the same generators, so that a bound is never fitted to
the episodes it then checks:

- ``calibration/tabletop-episodes-v1.jsonl``: 150 tabletop rearrangement episodes, one fresh
  tabletop each, drawn like the shipped ones (scene seeds in 0-9999, targets near the line) but
  from another generator seed and never on a scene seed the shipped episodes use;
- ``calibration/search-episodes-v1.jsonl``: 100 object-search episodes, 5 in each of 20 fresh
  apartments (``calibration/household-XXXX.json``, seeds 10-29; the shipped ones are seeds 0-9),
  drawn like the shipped ones.

    python -m scenes.make_calibration            # writes scenes/calibration/
    python -m scenes.make_calibration --check    # exits 1 if the shipped files differ
"""

from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path

import numpy as np

from scenes.shipped import ROOT, generator_main
from sim_envs.scenes.episodes import (
    Episode, EpisodeSet, episodes_text, load_episodes, tabletop_goals, tabletop_instruction,
)
from sim_envs.scenes.gen_household import generate_household
from sim_envs.scenes.gen_tabletop import generate_tabletop
from sim_envs.scenes.search_episodes import generate_search_episodes

__all__ = [
    "FOLDER", "TABLETOP_FILE", "SEARCH_FILE", "TABLETOP_GENERATOR_SEED", "TABLETOP_COUNT", "HOUSEHOLD_SEEDS",
    "SEARCH_PER_SCENE", "SEARCH_GENERATOR_SEED", "build_files", "main",
]

FOLDER = "calibration"
"""Folder under ``scenes/`` of the calibration data."""
TABLETOP_FILE = f"{FOLDER}/tabletop-episodes-v1.jsonl"
SEARCH_FILE = f"{FOLDER}/search-episodes-v1.jsonl"
TABLETOP_GENERATOR_SEED = 7001
TABLETOP_COUNT = 150
HOUSEHOLD_SEEDS = tuple(range(10, 30))
SEARCH_PER_SCENE = 5
SEARCH_GENERATOR_SEED = 7002


def _tabletop_episodes(shipped_seeds: set[int]) -> tuple[EpisodeSet, list]:
    """Like :func:`sim_envs.scenes.episodes.generate_tabletop_episodes`, skipping ``shipped_seeds``."""
    rng = np.random.default_rng(TABLETOP_GENERATOR_SEED)
    episodes, scenes = [], []
    for s in rng.permutation(10_000):
        if len(episodes) == TABLETOP_COUNT:
            break
        if int(s) in shipped_seeds:
            continue
        scene = generate_tabletop(int(s))
        goals = tabletop_goals(scene, rng)
        if not goals:
            continue
        episodes.append(Episode(
            episode_id=f"tabletop-cal-{len(episodes):04d}", scene=f"{FOLDER}/{scene.id}.json", scene_seed=int(s),
            instruction=tabletop_instruction(scene, goals), goals=goals, start_pose=None, max_steps=6,
        ))
        scenes.append(scene)
    return EpisodeSet("tabletop_rearrange", TABLETOP_GENERATOR_SEED, tuple(episodes)), scenes


def build_files() -> dict[str, str]:
    """Relative path under ``scenes/`` -> file text, for both episode files and every scene."""
    shipped = {int(e.scene_seed) for e in load_episodes(ROOT / "tabletop" / "episodes-v1.jsonl").episodes}
    tabletop, tables = _tabletop_episodes(shipped)
    files = {TABLETOP_FILE: episodes_text(tabletop)}
    for scene in tables:
        files[f"{FOLDER}/{scene.id}.json"] = json.dumps(scene.to_json(), indent=1)
    with tempfile.TemporaryDirectory() as tmp:  # the search generator reads scene files
        root = Path(tmp)
        (root / FOLDER).mkdir()
        paths = []
        for seed in HOUSEHOLD_SEEDS:
            rel = f"{FOLDER}/household-{seed:04d}.json"
            files[rel] = json.dumps(generate_household(seed).to_json(), indent=1)
            (root / rel).write_text(files[rel])
            paths.append(root / rel)
        search = generate_search_episodes(paths, per_scene=SEARCH_PER_SCENE, generator_seed=SEARCH_GENERATOR_SEED,
                                          scenes_root=root, id_prefix="search-cal")
    files[SEARCH_FILE] = episodes_text(search)
    return files


def main(argv: list[str] | None = None) -> int:
    return generator_main(build_files, FOLDER, __doc__.splitlines()[0], argv)


if __name__ == "__main__":
    sys.exit(main())
