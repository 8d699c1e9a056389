"""Regenerate the shipped tabletop v2 episodes and their scene files.

    python -m scenes.make_tabletop_v2            # writes scenes/tabletop-v2/
    python -m scenes.make_tabletop_v2 --check    # exits 1 if the shipped files differ

Scenes use the evaluation seeds of the split file (``splits().seeds["evaluation"]``), in order;
pushes are checked against the PyBullet Panda's inverse kinematics
(:class:`sim_envs.pybullet.reach.PandaReach`), so PyBullet must be installed.
"""

from __future__ import annotations

import json
import sys

from sim_envs.pybullet.reach import PandaReach
from scenes.shipped import generator_main
from sim_envs.scenes.episodes import episodes_text
from sim_envs.scenes.gen_tabletop_v2 import TABLE
from sim_envs.scenes.splits import splits
from sim_envs.scenes.tabletop_v2_episodes import generate_tabletop_v2_episodes

__all__ = ["GENERATOR_SEED", "COUNT", "FOLDER", "episode_files", "build_files", "main"]

GENERATOR_SEED = 2026
COUNT = 160
FOLDER = "tabletop-v2"


def episode_files(generator_seed: int, count: int, seeds, *, folder: str, episode_file: str,
                  id_prefix: str = "tabletop-v2", goal_groups: tuple[str, ...] | None = None) -> dict[str, str]:
    """Relative path under ``scenes/`` -> file text: ``count`` v2 rearrangement episodes drawn
    from ``seeds`` with pushes inside the PyBullet Panda's reach (``episode_file``; targets from
    ``goal_groups`` only when given) and every table they use (``<folder>/<scene id>.json``)."""
    reach = PandaReach(TABLE)
    try:
        episodes, scenes = generate_tabletop_v2_episodes(generator_seed, count, seeds, reach=reach.reachable, scene_dir=folder,
                                                         id_prefix=id_prefix, goal_groups=goal_groups)
    finally:
        reach.close()
    files = {episode_file: episodes_text(episodes)}
    for scene in scenes:
        files[f"{folder}/{scene.id}.json"] = json.dumps(scene.to_json(), indent=1)
    return files


def build_files(generator_seed: int = GENERATOR_SEED, count: int = COUNT) -> dict[str, str]:
    """Relative path under ``scenes/`` -> file text, for the episode file and every scene."""
    lo, hi = splits().seeds["evaluation"]
    return episode_files(generator_seed, count, range(lo, hi), folder=FOLDER, episode_file=f"{FOLDER}/episodes-v2.jsonl")


def main(argv: list[str] | None = None) -> int:
    return generator_main(build_files, FOLDER, __doc__.splitlines()[0], argv)


if __name__ == "__main__":
    sys.exit(main())
