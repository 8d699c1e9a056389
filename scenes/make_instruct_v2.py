"""The instruction episodes of ``instruct-v2`` (``scenes/instruct-v2/``): apartments and episodes
to report on, drawn before any planner or instruction agent was written.

- ``instruct-v2/household-v2-<seed>.json``: :data:`NUM_APARTMENTS` library apartments
  (:func:`~sim_envs.scenes.gen_household_v2.generate_household_v2`) on ``evaluation`` seeds from
  index :data:`SEED_OFFSET` on, seeds no other shipped file or training set uses;
- ``instruct-v2/instruct-episodes-v2.jsonl``: :data:`PER_SCENE` instruction episodes per apartment
  (:func:`~sim_envs.scenes.instruct_episodes.generate_instruction_episodes`: needs, rooms and
  relations in turn).

The development episodes are drawn the same way on the calibration apartments
(``calibration-v2/instruct-episodes-v2.jsonl``, :func:`dev_file`, written by
``python -m scenes.make_calibration_v2``).

    python -m scenes.make_instruct_v2            # writes scenes/instruct-v2/
    python -m scenes.make_instruct_v2 --check    # exits 1 if the shipped files differ
"""

from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path

from scenes.shipped import generator_main
from sim_envs.scenes.episodes import episodes_text
from sim_envs.scenes.gen_household_v2 import generate_household_v2
from sim_envs.scenes.instruct_episodes import generate_instruction_episodes
from sim_envs.scenes.splits import splits

__all__ = ["FOLDER", "EPISODE_FILE", "NUM_APARTMENTS", "SEED_OFFSET", "PER_SCENE", "GENERATOR_SEED", "DEV_FILE", "DEV_PER_SCENE",
           "DEV_GENERATOR_SEED", "apartment_seeds", "episode_file_text", "dev_file", "build_files", "main"]

FOLDER = "instruct-v2"
EPISODE_FILE = f"{FOLDER}/instruct-episodes-v2.jsonl"
NUM_APARTMENTS = 20
SEED_OFFSET = 5000
"""Index of the first apartment seed among the ``evaluation`` seeds (the shipped v2 apartments use
0-19, the tower's held-out views 0-99)."""
PER_SCENE = 8
GENERATOR_SEED = 4301
DEV_FILE = "calibration-v2/instruct-episodes-v2.jsonl"
DEV_PER_SCENE = 4
DEV_GENERATOR_SEED = 4302


def apartment_seeds() -> list[int]:
    """Seeds of the instruction apartments: ``evaluation`` seeds ``SEED_OFFSET ..`` ``SEED_OFFSET + NUM_APARTMENTS - 1``."""
    return splits().seeds_of("evaluation", SEED_OFFSET + NUM_APARTMENTS)[SEED_OFFSET:]


def episode_file_text(apartments: dict[str, str], *, per_scene: int, generator_seed: int, id_prefix: str) -> str:
    """The instruction episode file over ``apartments`` (relative path under ``scenes/`` -> file text)."""
    with tempfile.TemporaryDirectory() as tmp:  # the generator reads scene files
        root = Path(tmp)
        paths = []
        for rel, text in sorted(apartments.items()):
            (root / rel).parent.mkdir(parents=True, exist_ok=True)
            (root / rel).write_text(text)
            paths.append(root / rel)
        eps = generate_instruction_episodes(paths, per_scene=per_scene, generator_seed=generator_seed, scenes_root=root,
                                            id_prefix=id_prefix)
    return episodes_text(eps)


def dev_file(apartments: dict[str, str]) -> dict[str, str]:
    """``{DEV_FILE: text}``: the development instruction episodes over the calibration apartments."""
    return {DEV_FILE: episode_file_text(apartments, per_scene=DEV_PER_SCENE, generator_seed=DEV_GENERATOR_SEED,
                                        id_prefix="instruct-v2-dev")}


def build_files() -> dict[str, str]:
    """Relative path under ``scenes/`` -> file text: the apartments and the episode file."""
    files = {}
    for seed in apartment_seeds():
        scene = generate_household_v2(seed)
        files[f"{FOLDER}/{scene.id}.json"] = json.dumps(scene.to_json(), indent=1)
    files[EPISODE_FILE] = episode_file_text(files, per_scene=PER_SCENE, generator_seed=GENERATOR_SEED, id_prefix="instruct-v2")
    return files


def main(argv: list[str] | None = None) -> int:
    return generator_main(build_files, FOLDER, __doc__.splitlines()[0], argv)


if __name__ == "__main__":
    sys.exit(main())
