"""Multi-goal object search: chains of 2-4 goals in one apartment, revealed one at a time.

A chain episode is an ``object_search`` episode with several goals (each with its
``description`` and ``description_kind``), in order. The environment shows the first goal's
description; a stop within the success distance of the current goal reaches it and reveals the
next one, a stop anywhere else ends the chain (VLMaps' multi-goal protocol: success is counted
per position, "the first k goals in a row"). ``max_steps`` is the whole chain's budget. The
episode's ``instruction`` joins the descriptions with ", then " (for people; agents see one goal
at a time).

A map pays off here when a later goal was seen while looking for an earlier one, so consecutive
goals lie in different rooms.

"Explore, then fetch" episodes are chains with an exploration budget first (``explore_steps``):
the observation's goal reads :data:`conceptfusion.tasks.EXPLORE_GOAL` until the budget is spent,
then the goals follow one at a time, each with a smaller budget (:data:`FETCH_STEPS_PER_GOAL`):
what was mapped while exploring should find them.
"""

from __future__ import annotations

import math
import tempfile
from pathlib import Path
from typing import Sequence

import numpy as np

from planners.geodesic import geodesic_to_goal
from sim_envs.assets.library import is_library_asset
from sim_envs.scenes.descriptions import describe
from sim_envs.scenes.episodes import Episode, EpisodeFormatError, EpisodeSet, Goal, episodes_text, resolve_scene
from sim_envs.scenes.floorplan import occupancy_grid
from sim_envs.scenes.search_episodes import apartment_grid, goal_mask, room_of
from sim_envs.scenes.splits import SPLIT_GROUPS, object_group

__all__ = ["CHAIN_LENGTHS", "STEPS_PER_GOAL", "FETCH_EXPLORE_STEPS", "FETCH_STEPS_PER_GOAL", "THEN", "chain_instruction", "generate_chain_episodes", "chain_file_text",
           "check_chains_reachable"]

CHAIN_LENGTHS = (2, 3, 4)
"""Chain lengths, in turn."""
STEPS_PER_GOAL = 250
"""Step budget per goal (a chain of k goals has ``k * STEPS_PER_GOAL``), as a single-goal search."""
FETCH_EXPLORE_STEPS = 200
"""Exploration budget of an "explore, then fetch" episode."""
FETCH_STEPS_PER_GOAL = 150
"""Step budget per goal once the exploration is over."""
THEN = ", then "
"""What joins a chain's descriptions in its ``instruction``."""
_MAX_INSTRUCTION = 200


def chain_instruction(descriptions: Sequence[str]) -> str:
    """``["the plate", "the hand bell"]`` -> ``"the plate, then the hand bell"``."""
    return THEN.join(descriptions)


def generate_chain_episodes(
    scene_files: list[Path], *, per_scene: int = 1, generator_seed: int = 0, chain_lengths: tuple[int, ...] = CHAIN_LENGTHS,
    robot_radius: float = 0.25, success_distance: float = 1.0, scenes_root: str | Path | None = None,
    description_kinds: tuple[str, ...] = ("name", "synonym", "attribute", "function"), id_prefix: str = "chain-v2",
    goal_groups: tuple[str, ...] | None = None, explore_steps: int = 0, steps_per_goal: int = STEPS_PER_GOAL,
) -> EpisodeSet:
    """``per_scene`` chains for each scene file (paths under ``scenes_root``).

    Chain ``j`` (over the whole set) has ``chain_lengths[j % len]`` distinct goals, library
    instances of ``goal_groups`` (None: any library instance), each named by the next
    description kind that singles it out (kinds in turn over all goals); consecutive goals lie in
    different rooms; the start is a free cell (clearance >= robot radius + 0.1 m) outside the
    first goal's room from which every goal's success region can be reached. Everything follows
    from ``generator_seed``. ``explore_steps`` > 0 makes them "explore, then fetch" episodes: that
    many steps of exploration before the first goal is revealed, then ``steps_per_goal`` per goal.

    Raises:
        ValueError: a scene without rooms, an unknown split group, or a chain length < 2.
    """
    unknown = sorted(set(goal_groups or ()) - set(SPLIT_GROUPS))
    if unknown:
        raise ValueError(f"goal_groups: {unknown} are not split groups; expected some of {', '.join(SPLIT_GROUPS)}")
    if not chain_lengths or min(chain_lengths) < 2:
        raise ValueError(f"chain_lengths: expected lengths >= 2, got {chain_lengths!r}")
    rng = np.random.default_rng(generator_seed)
    episodes: list[Episode] = []
    described = 0
    for path in scene_files:
        scene, rel, occ, free, starts = apartment_grid(path, scenes_root=scenes_root, robot_radius=robot_radius)
        cx, cy = occ.centres()
        pool = [o for o in scene.objects
                if is_library_asset(o.asset) and (goal_groups is None or object_group(o) in goal_groups)]
        for _ in range(per_scene):
            length = chain_lengths[len(episodes) % len(chain_lengths)]
            for _attempt in range(40):
                order = [pool[int(i)] for i in rng.permutation(len(pool))]
                chain, rooms = [], []
                for obj in order:
                    room = room_of(scene, obj.position[:2])
                    if room is None or (rooms and room == rooms[-1]):
                        continue
                    chain.append(obj)
                    rooms.append(room)
                    if len(chain) == length:
                        break
                if len(chain) < length:
                    break  # this scene cannot hold a chain this long
                goals = []
                for i, obj in enumerate(chain):
                    for j in range(len(description_kinds)):
                        kind = description_kinds[(described + i + j) % len(description_kinds)]
                        phrase = describe(obj, scene.objects, kind, rng)
                        if phrase is not None:
                            goals.append(Goal(obj.id, description=phrase, description_kind=kind))
                            break
                if len(goals) < length:
                    continue
                instruction = chain_instruction([g.description for g in goals])
                if len(instruction) > _MAX_INSTRUCTION:
                    continue
                masks = [goal_mask(occ, *o.footprint(), success_distance) for o in chain]
                start = None
                for _ in range(40):
                    r, c = starts[int(rng.integers(len(starts)))]
                    xy = (float(cx[r, c]), float(cy[r, c]))
                    if room_of(scene, xy) in (None, rooms[0]):
                        continue
                    if all(math.isfinite(geodesic_to_goal(free, occ.origin, occ.cell, xy, m)) for m in masks):
                        start = xy
                        break
                if start is None:
                    continue
                described += length
                yaw = float(rng.uniform(-math.pi, math.pi))
                episodes.append(Episode(
                    episode_id=f"{id_prefix}-{len(episodes):04d}", scene=rel, scene_seed=scene.seed, instruction=instruction,
                    goals=tuple(goals), start_pose=(round(start[0], 3), round(start[1], 3), round(yaw, 4)),
                    max_steps=explore_steps + steps_per_goal * length, description_kind=None, explore_steps=explore_steps,
                ))
                break
    return EpisodeSet("object_search", int(generator_seed), tuple(episodes))


def chain_file_text(apartments: dict[str, str], *, per_scene: int, generator_seed: int, id_prefix: str,
                    goal_groups: tuple[str, ...] | None = None, **options) -> str:
    """The text of a chain episode file drawn in ``apartments`` (path relative to ``scenes/`` ->
    scene file text, in order; :func:`generate_chain_episodes` with ``options``), for generating
    scripts that write the apartments in the same run."""
    with tempfile.TemporaryDirectory() as tmp:  # the generator reads scene files
        root = Path(tmp)
        paths = []
        for rel, text in apartments.items():
            (root / rel).parent.mkdir(parents=True, exist_ok=True)
            (root / rel).write_text(text)
            paths.append(root / rel)
        eps = generate_chain_episodes(paths, per_scene=per_scene, generator_seed=generator_seed, scenes_root=root,
                                      id_prefix=id_prefix, goal_groups=goal_groups, **options)
    return episodes_text(eps)


def check_chains_reachable(episodes: Sequence[Episode], *, where: str, robot_radius: float = 0.25,
                           success_distance: float = 1.0, scenes_root: str | Path | None = None) -> None:
    """Refuse, before any episode runs, a multi-goal episode with a goal the base cannot reach
    from its start (on the floor plan inflated by ``robot_radius``). ``where`` names the file.

    Raises:
        EpisodeFormatError: naming the file, the episode's line (header first, as loaded), the
            field (``goals[k].object_id``) and why.
    """
    grids: dict = {}
    for line, ep in enumerate(episodes, start=2):
        if len(ep.goals) < 2:
            continue
        scene = resolve_scene(ep.scene, ep.scene_seed, scenes_root=scenes_root)
        if scene.id not in grids:
            occ = occupancy_grid(scene, cell=0.05)
            grids[scene.id] = (occ, occ.clearance() > robot_radius)
        occ, free = grids[scene.id]
        objects = {o.id: o for o in scene.objects}
        xy = tuple(float(v) for v in ep.start_pose[:2])
        for k, goal in enumerate(ep.goals):
            obj = objects[goal.object_id]
            if not math.isfinite(geodesic_to_goal(free, occ.origin, occ.cell, xy, goal_mask(occ, *obj.footprint(), success_distance))):
                raise EpisodeFormatError(f"{where}:line {line}: episode {ep.episode_id!r}: goals[{k}].object_id "
                                         f"{goal.object_id!r} cannot be reached from the start pose {list(xy)}")
