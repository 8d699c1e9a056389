"""Regenerate the shipped tabletop episodes and their scene files.

    python -m scenes.make_tabletop_episodes            # writes scenes/tabletop/
    python -m scenes.make_tabletop_episodes --check    # exits 1 if the shipped files differ
"""

from __future__ import annotations

import json
import sys

from scenes.shipped import generator_main
from sim_envs.scenes.episodes import episodes_text, generate_tabletop_episodes

__all__ = ["GENERATOR_SEED", "COUNT", "build_files", "main"]

GENERATOR_SEED = 2023
COUNT = 150


def build_files(generator_seed: int = GENERATOR_SEED, count: int = COUNT) -> dict[str, str]:
    """Relative path under ``scenes/`` -> file text, for the episode file and every scene."""
    episodes, scenes = generate_tabletop_episodes(generator_seed, count)
    files = {"tabletop/episodes-v1.jsonl": episodes_text(episodes)}
    for scene in scenes:
        files[f"tabletop/{scene.id}.json"] = json.dumps(scene.to_json(), indent=1)
    return files


def main(argv: list[str] | None = None) -> int:
    return generator_main(build_files, "tabletop", __doc__.splitlines()[0], argv)


if __name__ == "__main__":
    sys.exit(main())
