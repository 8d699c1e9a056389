"""Instruction episodes: search goals named by a need, a place or a relation instead of an object.

The paper's planner-in-the-loop setting: the instruction says what the user wants, and several
objects of the apartment may satisfy it. Three kinds (:data:`~sim_envs.scenes.episodes.INSTRUCTION_KINDS`):

- ``need``: what the object is for, from the object library's function metadata ("I need
  something to write with") or a need that a whole taxonomy group answers (:data:`GROUP_NEEDS`,
  "find something to eat": every food, fruit and pastry);
- ``room``: a need or a taxonomy group in one room, named by the room ("a toy in the living
  room") or by an object only that room holds ("something to eat in the room with the kettle");
  at least one object outside the room answers the need too, so the room matters;
- ``relation``: an object by its relation to another object, from the scene graph: what stands
  on it ("something on the tray"), what lies in it ("something in the bowl"), or a group member
  next to it ("the toy next to the vase"; within :data:`NEAR` of it, and another member of the
  group lies over :data:`FAR` away).

Anchors and room marks are objects of a category the apartment holds once, never furniture: the
maps name what their perception grounds, and the privileged ``oracle-open`` perception grounds
the library's objects only.

Every episode's goal lists *all* the objects that satisfy its instruction: ``object_id`` is the
one nearest the start along free floor (the shortest path and the oracle head for it), ``accept``
the others (:class:`~sim_envs.scenes.episodes.Goal`). The start is a free cell in a room holding
none of them when there is one (else in another room than the nearest), from which the success
region is reachable. Left-of and right-of relations are not generated: they depend on where the
viewer stands, and an apartment search has no fixed viewpoint.

Everything follows from the apartment files and ``generator_seed``
(:func:`generate_instruction_episodes`). The shipped files are written by
``python -m scenes.make_instruct_v2``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from planners.geodesic import geodesic_to_goal
from sim_envs.scenes.descriptions import describable, referents
from sim_envs.scenes.episodes import INSTRUCTION_KINDS, Episode, EpisodeSet, Goal
from sim_envs.scenes.format import Scene, SceneObject
from sim_envs.scenes.search_episodes import apartment_grid, goal_mask

__all__ = ["GROUP_NEEDS", "GROUP_NOUNS", "NEAR", "FAR", "Instruction", "instructions_of", "generate_instruction_episodes"]

GROUP_NEEDS: dict[str, str] = {
    "food": "something to eat",
    "fruit": "a piece of fruit",
    "drinkware": "something to drink out of",
    "cutlery": "something to eat with",
    "cookware": "something to cook with",
    "toy": "something for a child to play with",
    "cleaning supply": "something to clean with",
    "lighting": "a source of light",
    "stationery": "something to write or draw with",
    "office supply": "something for the office",
    "hand tool": "a tool to fix things with",
    "sports equipment": "something to exercise with",
    "personal care": "something for washing up",
    "decor": "something decorative",
    "electronics": "an electronic device",
    "storage": "something to store things in",
}
"""Taxonomy group -> a need every member of the group answers."""

GROUP_NOUNS: dict[str, str] = {
    "food": "food", "fruit": "fruit", "drinkware": "drinking vessel", "cutlery": "piece of cutlery", "cookware": "pot or pan",
    "toy": "toy", "cleaning supply": "cleaning item", "lighting": "light", "stationery": "writing tool",
    "office supply": "office item", "hand tool": "tool", "sports equipment": "piece of sports gear",
    "personal care": "toiletry", "decor": "decoration", "electronics": "gadget", "storage": "storage box",
}
"""Taxonomy group -> how a relation instruction names one of its members ("the toy next to the vase")."""

NEAR = 0.6
"""Metres between footprints within which an object is next to an anchor."""
FAR = 2.0
"""A near-relation needs another group member at least this far (m) from the anchor."""

_NEED_TEMPLATES = ("I need {}", "find {}", "take me to {}", "go to {}")
_ROOM_TEMPLATES = ("find {} in the {}", "I need {} from the {}", "go to {} in the {}")
_CONTAINER_GROUPS = frozenset({"container", "storage", "cookware", "basket", "crate", "box", "bucket"})


@dataclass(frozen=True)
class Instruction:
    """One instruction an apartment supports, and every object that satisfies it."""

    kind: str
    """One of :data:`~sim_envs.scenes.episodes.INSTRUCTION_KINDS`."""
    text: str
    satisfying: tuple[str, ...]
    """Object ids, sorted."""


def _footprint_gap(a: SceneObject, b: SceneObject) -> float:
    (alo, ahi), (blo, bhi) = a.footprint(), b.footprint()
    d = np.maximum(np.maximum(alo - bhi, blo - ahi), 0.0)
    return float(np.hypot(d[0], d[1]))


def _unique_categories(items) -> dict[str, object]:
    """Category -> item, for categories exactly one item has."""
    seen: dict[str, list] = {}
    for it in items:
        seen.setdefault(it.category, []).append(it)
    return {c: v[0] for c, v in seen.items() if len(v) == 1}


def _room_name(scene: Scene, xy) -> str | None:
    for r in scene.rooms:
        if r.contains(xy):
            return r.name
    return None


def instructions_of(scene: Scene) -> dict[str, list[Instruction]]:
    """Every instruction of each kind that ``scene`` supports, in a fixed order.

    Returns: kind -> instructions (a kind may have none).
    """
    objs = list(scene.objects)
    info = {o.id: describable(o) for o in objs}
    room = {o.id: _room_name(scene, o.position[:2]) for o in objs}
    out: dict[str, list[Instruction]] = {k: [] for k in INSTRUCTION_KINDS}

    # needs: a category's function phrase (every object answering to it), or a group's need
    needs: list[tuple[str, tuple[str, ...]]] = []
    for phrase in sorted({f for d in info.values() for f in d.functions}):
        needs.append((phrase, tuple(sorted(o.id for o in referents(phrase, objs)))))
    for group, phrase in GROUP_NEEDS.items():
        members = tuple(sorted(o.id for o in objs if group in info[o.id].parents))
        if members:
            needs.append((phrase, members))
    for k, (phrase, ids) in enumerate(needs):
        out["need"].append(Instruction("need", _NEED_TEMPLATES[k % len(_NEED_TEMPLATES)].format(phrase), ids))

    # rooms: a need in one room, the room named or singled out by an object only it holds
    unique_objects = _unique_categories(objs)
    mark_room = {c: room[o.id] for c, o in unique_objects.items()}
    k = 0
    for phrase, ids in needs:
        for name in sorted({room[i] for i in ids if room[i] is not None}):
            inside = tuple(i for i in ids if room[i] == name)
            if len(inside) == len(ids):
                continue  # the room changes nothing
            marks = sorted(c for c, r in mark_room.items() if r == name and not set(ids) & {unique_objects[c].id})
            if k % 2 and marks:
                text = f"{phrase} in the room with the {marks[k // 2 % len(marks)]}"
            else:
                text = _ROOM_TEMPLATES[k % len(_ROOM_TEMPLATES)].format(phrase, name)
            out["room"].append(Instruction("room", text, inside))
            k += 1

    # relations: on / in an object, next to an object
    for sid, thing in sorted((o.id, o) for o in unique_objects.values()):
        on_it = tuple(sorted(o.id for o in objs if o.support == sid))
        if not on_it:
            continue
        inside = bool(_CONTAINER_GROUPS & ({thing.category} | set(info[sid].parents)))
        out["relation"].append(Instruction("relation", f"something {'in' if inside else 'on'} the {thing.category}", on_it))
    for cat, anchor in sorted(unique_objects.items()):
        for group in sorted(GROUP_NEEDS):
            members = [o for o in objs if o.id != anchor.id and group in info[o.id].parents]
            near = tuple(sorted(o.id for o in members if _footprint_gap(o, anchor) <= NEAR))
            if near and any(_footprint_gap(o, anchor) >= FAR for o in members):
                out["relation"].append(Instruction("relation", f"the {GROUP_NOUNS[group]} next to the {cat}", near))
    return out


def generate_instruction_episodes(
    scene_files: list[Path], *, per_scene: int = 8, generator_seed: int = 0, max_steps: int = 250,
    robot_radius: float = 0.25, success_distance: float = 1.0, scenes_root: str | Path | None = None,
    id_prefix: str = "instruct-v2",
) -> EpisodeSet:
    """``per_scene`` instruction episodes for each apartment file, kinds in turn (need, room,
    relation, need, ...; a kind an apartment cannot give is skipped for the next).

    Instructions of a kind are drawn without repetition from :func:`instructions_of`; the
    episode's goal is the satisfying object nearest the start along free floor, the others its
    ``accept``. Raises ``ValueError`` for a scene without rooms.
    """
    rng = np.random.default_rng(generator_seed)
    episodes: list[Episode] = []
    for path in scene_files:
        scene, rel, occ, free, starts = apartment_grid(path, scenes_root=scenes_root, robot_radius=robot_radius)
        cx, cy = occ.centres()
        by_id = {o.id: o for o in scene.objects}
        pools = {kind: [items[int(i)] for i in rng.permutation(len(items))] for kind, items in instructions_of(scene).items()}
        made, turn = 0, 0
        while made < per_scene and any(pools.values()):
            kind = INSTRUCTION_KINDS[turn % len(INSTRUCTION_KINDS)]
            turn += 1
            if not pools[kind]:
                continue
            ins = pools[kind].pop(0)
            episode = _place(ins, scene, rel, occ, free, starts, cx, cy, by_id, rng, robot_radius=robot_radius,
                             success_distance=success_distance, max_steps=max_steps,
                             episode_id=f"{id_prefix}-{len(episodes):04d}")
            if episode is not None:
                episodes.append(episode)
                made += 1
    return EpisodeSet("object_search", int(generator_seed), tuple(episodes))


def _place(ins: Instruction, scene, rel, occ, free, starts, cx, cy, by_id, rng, *, robot_radius, success_distance, max_steps,
           episode_id) -> Episode | None:
    """An episode for ``ins``: a start and the goal nearest it (None: no start reaches a goal)."""
    rooms = {_room_name(scene, by_id[i].position[:2]) for i in ins.satisfying}
    masks = {i: goal_mask(occ, *by_id[i].footprint(), success_distance) for i in ins.satisfying}
    empty_rooms = [r.name for r in scene.rooms if r.name not in rooms]
    for _ in range(60):
        r, c = starts[int(rng.integers(len(starts)))]
        xy = (float(cx[r, c]), float(cy[r, c]))
        where = _room_name(scene, xy)
        if where is None or (empty_rooms and where not in empty_rooms):
            continue
        dist = {i: geodesic_to_goal(free, occ.origin, occ.cell, xy, m) for i, m in masks.items()}
        reachable = sorted((d, i) for i, d in dist.items() if math.isfinite(d))
        if not reachable or reachable[0][0] <= success_distance:
            continue
        goal = reachable[0][1]
        accept = tuple(i for i in ins.satisfying if i != goal)
        yaw = float(rng.uniform(-math.pi, math.pi))
        return Episode(
            episode_id=episode_id, scene=rel, scene_seed=scene.seed, instruction=ins.text,
            goals=(Goal(goal, accept=accept),), start_pose=(round(xy[0], 3), round(xy[1], 3), round(yaw, 4)),
            max_steps=max_steps, instruction_kind=ins.kind,
        )
    return None
