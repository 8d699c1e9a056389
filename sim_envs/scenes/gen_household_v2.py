"""Household v2: the v1 apartments (rooms, walls, doors, furniture) filled from the object library.

Each apartment holds 28-35 small objects, one per library category (so at least 20 categories
and a unique name each, "red mug"), on furniture tops, shelf levels, inside open cabinets and
inside open library containers (bowls, baskets, crates, trays: 2-4 of them, one object in
each), plus 1-2 furniture-sized library objects (chair, stool, bench, side table, bookshelf)
standing on the floor against a wall, out of the doorways, without cutting a room off. Objects
lean towards the room they belong in (kitchenware in the kitchen, stationery in the study ...).

**Splits** (:mod:`sim_envs.scenes.splits`): a scene's seed fixes its role, and the role which
instances it may use: tower training and calibration seeds only ``train`` instances, tower
validation seeds ``train`` and ``val``, evaluation seeds every instance (so suites can split
seen / held-out instance / held-out category). A seed outside every range is refused.

Randomness: everything follows from the seed (``np.random.default_rng(seed)``); the apartment
is drawn exactly as :func:`~sim_envs.scenes.gen_household.generate_household` draws it.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from sim_envs.assets.library import catalogue, instance_size
from sim_envs.assets.library.catalogue import Instance
from sim_envs.scenes.floorplan import reachable_rooms
from sim_envs.scenes.format import Scene, SceneObject
from sim_envs.scenes.gen_household import door_keep_out, furnished_apartment, place_on_surface, support_surfaces
from sim_envs.scenes.household_format import LIBRARY_CONTAINERS, container_floor
from sim_envs.scenes.splits import splits

__all__ = ["generate_household_v2", "FLOOR_CATEGORIES", "INSTANCE_ROLES", "ROOM_GROUPS", "allowed_instances"]

FLOOR_CATEGORIES = ("chair", "stool", "bench", "side table", "bookshelf")
"""Furniture-sized library categories: they stand on the floor, never on furniture."""

INSTANCE_ROLES: dict[str, tuple[str, ...]] = {
    "tower_train": ("train",),
    "tower_val": ("train", "val"),
    "calibration": ("train",),
    "evaluation": ("train", "val", "test"),
    "sealed": ("train", "test"),
}
"""Seed role -> instance roles a scene of that role may use."""

ROOM_GROUPS: dict[str, frozenset[str]] = {
    "kitchen": frozenset({"kitchenware", "tableware", "cookware", "cutlery", "food", "fruit", "pastry", "drinkware", "appliance"}),
    "study": frozenset({"office supply", "stationery", "electronics", "reading material", "hand tool", "tool"}),
    "living room": frozenset({"decor", "toy", "sports equipment", "lighting", "plant"}),
    "bedroom": frozenset({"clothing", "household linen", "personal care"}),
}
"""Taxonomy groups whose objects lean towards a room type."""

_PREFER_ROOM = 0.7
_WALL_CLEAR = 0.07  # half a wall plus 2 cm
_YAWS = {"S": math.pi, "N": 0.0, "E": -math.pi / 2, "W": math.pi / 2}


def allowed_instances(seed: int) -> dict[str, list[Instance]]:
    """Category -> instances (catalogue order) a scene with this seed may use, by its seed role.

    Raises:
        ValueError: the seed lies in no seed range of the split file.
    """
    sp = splits()
    role = sp.seed_role(seed)
    if role not in INSTANCE_ROLES:
        ranges = ", ".join(f"{k} [{a}, {b})" for k, (a, b) in sp.seeds.items())
        raise ValueError(f"seed {seed}: expected a seed in a split seed range ({ranges})")
    roles = INSTANCE_ROLES[role]
    out: dict[str, list[Instance]] = {}
    for inst in catalogue().instances.values():
        if sp.instances.get(inst.id) in roles:
            out.setdefault(inst.category, []).append(inst)
    return out


@lru_cache(maxsize=None)
def _size(instance_id: str) -> tuple[float, float, float]:
    return tuple(round(float(v), 4) for v in instance_size(instance_id))


def _object(oid: str, inst: Instance) -> SceneObject:
    cat = catalogue().categories[inst.category]
    phrases = (f"a {inst.color} {cat.name}",) + tuple(f"a {s}" for s in cat.synonyms[:2]) + tuple(cat.functions[:1])
    return SceneObject(oid, f"{inst.color} {cat.name}", cat.name, inst.asset, inst.color, (0.0, 0.0, 0.0), 0.0, _size(inst.id), phrases)


def _home_room(category: str) -> str | None:
    groups = set(catalogue().ancestors(category))
    return next((room for room, g in ROOM_GROUPS.items() if groups & g), None)


def _pick(rng, pool: dict[str, list[Instance]], category: str) -> Instance:
    insts = pool[category]
    return insts[int(rng.integers(len(insts)))]


def _floor_object(rng, scene: Scene, oid: str, inst: Instance, door_spans: dict, blocked: list) -> SceneObject | None:
    """A furniture-sized object with its back to a wall of a random room, or None."""
    room = scene.rooms[int(rng.integers(len(scene.rooms)))]
    proto = _object(oid, inst)
    side = "SENW"[int(rng.integers(4))]
    yaw = _YAWS[side]
    w, d = proto.size[0], proto.size[1]
    (x0, y0), (x1, y1) = room.floor
    ix0, iy0, ix1, iy1 = x0 + _WALL_CLEAR, y0 + _WALL_CLEAR, x1 - _WALL_CLEAR, y1 - _WALL_CLEAR
    along_lo, along_hi = (ix0, ix1) if side in "NS" else (iy0, iy1)
    if along_hi - along_lo <= w:
        return None
    t = float(rng.uniform(along_lo + w / 2, along_hi - w / 2))
    x, y = {"N": (t, iy1 - d / 2), "S": (t, iy0 + d / 2), "E": (ix1 - d / 2, t), "W": (ix0 + d / 2, t)}[side]
    obj = SceneObject(proto.id, proto.name, proto.category, proto.asset, proto.color, (round(x, 4), round(y, 4), 0.0),
                      round(yaw, 4), proto.size, proto.phrases, "floor")
    lo, hi = obj.footprint()
    keep = door_keep_out(door_spans.get(room.id, [])) + [f.footprint() for f in scene.furniture] + blocked
    if any(np.all(np.minimum(hi, h2) - np.maximum(lo, l2) > -0.12) for l2, h2 in keep):
        return None
    return obj


def _inside(rng, oid: str, inst: Instance, box: SceneObject) -> SceneObject | None:
    """``inst`` standing on the inner floor of container ``box`` (centred), or None if it does not fit."""
    proto = _object(oid, inst)
    share = 0.5 if box.category == "bowl" else 0.75
    if max(proto.size[:2]) > share * min(box.size[:2]) or proto.size[2] > 0.3:
        return None
    x, y, z = box.position
    zf = z + container_floor(box.asset, box.size)
    return SceneObject(proto.id, proto.name, proto.category, proto.asset, proto.color, (x, y, round(zf, 4)),
                       round(float(rng.uniform(-math.pi, math.pi)), 4), proto.size, proto.phrases, box.id)


def _populate(rng, scene: Scene, door_spans: dict, pool: dict[str, list[Instance]]) -> list[SceneObject]:
    furniture = list(scene.furniture)
    surfaces = support_surfaces(furniture)
    taken: dict[int, list] = {i: [] for i in range(len(surfaces))}
    room_name = [scene.room_at(f.position[:2]).name if scene.room_at(f.position[:2]) else None for f, _, _ in surfaces]
    tops = [i for i, (_, s, _) in enumerate(surfaces) if s.kind == "top"] or list(range(len(surfaces)))
    small = [c for c in pool if c not in FLOOR_CATEGORIES]
    order = [small[int(k)] for k in rng.permutation(len(small))]
    objects: list[SceneObject] = []

    def put(inst: Instance, where: list[int]) -> SceneObject | None:
        proto = _object(f"obj{len(objects)}", inst)
        home = _home_room(inst.category)
        preferred = [i for i in where if room_name[i] == home]
        for _ in range(12):
            cands = preferred if preferred and rng.random() < _PREFER_ROOM else where
            i = cands[int(rng.integers(len(cands)))]
            f, s, clear = surfaces[i]
            o = place_on_surface(rng, proto, f, s, clear, taken[i])
            if o is not None:
                objects.append(o)
                return o
        return None

    containers = [c for c in order if c in LIBRARY_CONTAINERS]
    boxes = []
    for c in containers[: int(rng.integers(2, 5))]:
        order.remove(c)
        inst = _pick(rng, pool, c)
        if container_floor(inst.asset, _size(inst.id)) is None:
            continue
        o = put(inst, tops)
        if o is not None:
            boxes.append(o)
    for box in boxes:  # one small thing inside each container
        for c in list(order):
            o = _inside(rng, f"obj{len(objects)}", _pick(rng, pool, c), box)
            if o is not None:
                objects.append(o)
                order.remove(c)
                break
    target = int(rng.integers(28, 36))
    everywhere = list(range(len(surfaces)))
    for c in list(order):
        if len(objects) >= target:
            break
        if put(_pick(rng, pool, c), everywhere) is not None:
            order.remove(c)
    floor_cats = [c for c in FLOOR_CATEGORIES if c in pool]
    blocked: list = []
    for c in [floor_cats[int(k)] for k in rng.permutation(len(floor_cats))][: int(rng.integers(1, 3))]:
        for _ in range(30):
            o = _floor_object(rng, scene, f"obj{len(objects)}", _pick(rng, pool, c), door_spans, blocked)
            if o is None:
                continue
            trial = Scene(scene.id, scene.kind, scene.seed, None, tuple(objects) + (o,), None, {}, scene.rooms, scene.walls, scene.furniture)
            if reachable_rooms(trial) == {r.id for r in scene.rooms}:
                objects.append(o)
                blocked.append(o.footprint())
                break
    return objects


def generate_household_v2(seed: int, *, min_objects: int = 25, min_categories: int = 20) -> Scene:
    """A v2 apartment (scene id ``household-v2-<seed>``) filled from the object library.

    Raises:
        ValueError: ``seed`` outside every seed range of the split file.
        RuntimeError: fewer than ``min_objects`` objects or ``min_categories`` categories placed.
    """
    pool = allowed_instances(seed)
    rng = np.random.default_rng(seed)
    scene, door_spans = furnished_apartment(rng, seed, f"household-v2-{seed}")
    objects = _populate(rng, scene, door_spans, pool)
    n_cat = len({o.category for o in objects})
    if len(objects) < min_objects or n_cat < min_categories:
        raise RuntimeError(
            f"generate_household_v2({seed}): placed {len(objects)} objects of {n_cat} categories, "
            f"expected at least {min_objects} of {min_categories}"
        )
    return Scene(scene.id, "household", int(seed), None, tuple(objects), None, {}, scene.rooms, scene.walls, scene.furniture)
