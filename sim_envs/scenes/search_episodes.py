"""Object-search episodes over household scenes: generation and the shipped default set.

An episode names a household scene, one goal object, the goal description the agent receives
("the red mug") and a start pose for the base in a different room from the goal, from which the
goal is reachable (the success region has a finite geodesic distance).

    python -m sim_envs.scenes.search_episodes    # regenerates scenes/household/episodes-v1.jsonl

Version 2 episodes (:mod:`sim_envs.scenes.search_episodes_v2`) name the goal by name, synonym,
attribute or function (:func:`sim_envs.scenes.descriptions.describe`) and record which.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from planners.geodesic import geodesic_to_goal
from sim_envs.assets.library import is_library_asset
from sim_envs.scenes.descriptions import describe
from sim_envs.scenes.episodes import SCENES_ROOT, Episode, EpisodeSet, Goal, load_episodes, save_episodes
from sim_envs.scenes.floorplan import occupancy_grid
from sim_envs.scenes.format import Scene, load_scene
from sim_envs.scenes.splits import SPLIT_GROUPS, object_group

__all__ = ["generate_search_episodes", "default_search_episodes", "DEFAULT_SEARCH_FILE", "room_of", "goal_mask", "apartment_grid"]

DEFAULT_SEARCH_FILE = SCENES_ROOT / "household" / "episodes-v1.jsonl"
"""The shipped object-search episodes."""


def room_of(scene: Scene, xy) -> str | None:
    """Id of the room whose floor contains ``xy`` (None: in no room)."""
    for r in scene.rooms:
        if r.contains(xy):
            return r.id
    return None


def goal_mask(occ, lo, hi, radius: float) -> np.ndarray:
    """Cells of an occupancy grid within ``radius`` (m) of a footprint ``lo``-``hi``: the goal's success region.

    Shape: ``lo``, ``hi`` (2,) -> (H, W) bool over ``occ``'s cells."""
    cx, cy = occ.centres()
    dx = np.maximum(np.maximum(lo[0] - cx, 0), cx - hi[0])
    dy = np.maximum(np.maximum(lo[1] - cy, 0), cy - hi[1])
    return np.hypot(dx, dy) <= radius


def apartment_grid(path, *, scenes_root=None, robot_radius: float = 0.25):
    """What an episode generator needs of an apartment file: the scene, its path relative to
    ``scenes_root`` (default: the shipped ``scenes/``), its 5 cm occupancy grid, the free cells for
    a base of ``robot_radius`` and the cells a start may take (clearance >= radius + 0.1 m).

    Shape: returns ``(scene, rel, occ, free (H, W) bool, starts (K, 2) row/col)``.

    Raises:
        ValueError: a scene without rooms.
    """
    path = Path(path)
    scene = load_scene(path)
    if not scene.rooms:
        raise ValueError(f"{path}: expected a household scene with rooms")
    rel = path.resolve().relative_to(Path(scenes_root or SCENES_ROOT).resolve()).as_posix()
    occ = occupancy_grid(scene, cell=0.05)
    clearance = occ.clearance()
    return scene, rel, occ, clearance > robot_radius, np.argwhere(clearance > robot_radius + 0.1)


def generate_search_episodes(
    scene_files: list[Path], *, per_scene: int = 5, generator_seed: int = 0, max_steps: int = 250,
    robot_radius: float = 0.25, success_distance: float = 1.0, scenes_root: str | Path | None = None,
    description_kinds: tuple[str, ...] | None = None, id_prefix: str = "search-v1", goal_groups: tuple[str, ...] | None = None,
) -> EpisodeSet:
    """``per_scene`` episodes for each scene file (paths under ``scenes/``).

    Goals are distinct objects of the scene; the start is a free cell (clearance >= robot radius
    + 0.1 m) in another room, with a finite geodesic distance to the goal's success region.
    Everything follows from ``generator_seed``. Scene paths in the episodes are relative to
    ``scenes_root`` (default: the shipped ``scenes/`` folder).

    ``description_kinds`` None: the instruction is ``"the <object name>"`` (version 1). Otherwise
    episode ``k`` asks for kind ``description_kinds[k % len]`` (then the following kinds, when no
    description of that kind singles the goal out; a goal no kind singles out is skipped) and
    records it in ``description_kind`` (the episode's and its goal's, with the goal's
    ``description``); descriptions draw from their own generator (seeded
    ``generator_seed + 1``), so the goals and starts are those of version 1. Episode ids read
    ``<id_prefix>-NNNN``. ``goal_groups`` (split groups of
    :func:`~sim_envs.scenes.splits.object_group`, e.g. ``("validation",)``) limits the goals to
    library instances of those groups; None: any object.

    Raises:
        ValueError: a scene without rooms, or an unknown split group.
    """
    unknown = sorted(set(goal_groups or ()) - set(SPLIT_GROUPS))
    if unknown:
        raise ValueError(f"goal_groups: {unknown} are not split groups; expected some of {', '.join(SPLIT_GROUPS)}")
    rng = np.random.default_rng(generator_seed)
    text_rng = np.random.default_rng(generator_seed + 1)
    episodes = []
    for path in scene_files:
        scene, rel, occ, free, starts = apartment_grid(path, scenes_root=scenes_root, robot_radius=robot_radius)
        cx, cy = occ.centres()
        order = rng.permutation(len(scene.objects))
        made = 0
        for oi in order:
            if made >= per_scene:
                break
            obj = scene.objects[int(oi)]
            if goal_groups is not None and not (is_library_asset(obj.asset) and object_group(obj) in goal_groups):
                continue
            instruction, kind = f"the {obj.name}", None
            if description_kinds:
                k0 = len(episodes)
                for j in range(len(description_kinds)):
                    kind = description_kinds[(k0 + j) % len(description_kinds)]
                    phrase = describe(obj, scene.objects, kind, text_rng)
                    if phrase is not None:
                        instruction = phrase
                        break
                else:
                    continue
            goal_room = room_of(scene, obj.position[:2])
            lo, hi = obj.footprint()
            mask = goal_mask(occ, lo, hi, success_distance)
            for _ in range(40):
                r, c = starts[int(rng.integers(len(starts)))]
                xy = (float(cx[r, c]), float(cy[r, c]))
                if room_of(scene, xy) in (None, goal_room):
                    continue
                if not math.isfinite(geodesic_to_goal(free, occ.origin, occ.cell, xy, mask)):
                    continue
                yaw = float(rng.uniform(-math.pi, math.pi))
                episodes.append(
                    Episode(
                        episode_id=f"{id_prefix}-{len(episodes):04d}", scene=rel, scene_seed=scene.seed,
                        instruction=instruction,
                        goals=(Goal(obj.id, description=instruction, description_kind=kind) if kind else Goal(obj.id),),
                        start_pose=(round(xy[0], 3), round(xy[1], 3), round(yaw, 4)), max_steps=max_steps,
                        description_kind=kind,
                    )
                )
                made += 1
                break
    return EpisodeSet("object_search", int(generator_seed), tuple(episodes))


def default_search_episodes() -> EpisodeSet:
    """The shipped object-search episodes (``scenes/household/episodes-v1.jsonl``)."""
    return load_episodes(DEFAULT_SEARCH_FILE)


def main() -> None:
    files = sorted((SCENES_ROOT / "household").glob("household-*.json"))
    if not files:
        raise SystemExit(f"no household scene files under {SCENES_ROOT / 'household'}")
    eps = generate_search_episodes(files, per_scene=5, generator_seed=0)
    save_episodes(eps, DEFAULT_SEARCH_FILE)
    print(f"wrote {len(eps.episodes)} episodes to {DEFAULT_SEARCH_FILE}")


if __name__ == "__main__":
    main()
