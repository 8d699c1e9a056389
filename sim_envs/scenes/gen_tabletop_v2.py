"""Seeded tabletop scenes v2: 4-12 objects from the object library's long tail on the v1 table.

The table, its material and the dividing line (along y through x = 0) are v1's
(:func:`~sim_envs.scenes.gen_tabletop.generate_tabletop`); the objects are library instances
(scene asset ``"lib:<instance id>"``, at the instance's own size) instead of the seven primitive
kinds. What a scene may draw follows the split file (:func:`sim_envs.scenes.splits.splits`): the
seed's role fixes the instance pool (:data:`POOL_ROLES`): evaluation scenes draw from every
instance, so test suites can split seen / held-out instance / held-out category; tower
training scenes only from train instances.

Only instances that suit a table are drawn (:func:`table_instances`): no furniture (chairs,
stools, benches, side tables, bookshelves), nothing that will not stand still
(:data:`UNSTABLE_CATEGORIES`), longest horizontal side at most :data:`MAX_FOOTPRINT`, height at
most :data:`MAX_HEIGHT`.

Randomness: everything follows from ``seed`` (``np.random.default_rng(seed)``).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from conceptfusion.errors import SimError
from sim_envs.assets.library import Instance, catalogue, instance_size
from sim_envs.scenes.format import Scene, SceneObject, Table
from sim_envs.scenes.splits import splits

__all__ = [
    "MAX_FOOTPRINT", "MAX_HEIGHT", "NUM_OBJECTS", "POOL_ROLES", "EXCLUDED_GROUPS", "UNSTABLE_CATEGORIES", "TABLE", "table_instances", "instance_pool",
    "scene_id_v2", "generate_tabletop_v2",
]

MAX_FOOTPRINT = 0.30
"""Longest horizontal side (m) of an instance on a table."""
MAX_HEIGHT = 0.35
"""Tallest instance (m) on a table."""
NUM_OBJECTS = (4, 12)
"""Fewest and most objects on a table (inclusive)."""
EXCLUDED_GROUPS = ("furniture",)
"""Categories under these groups never stand on a table."""
UNSTABLE_CATEGORIES = ("headphones", "spinning top", "dumbbell")
"""Categories whose instances do not stand still on a table (an arc on its edge, a top on its
point, a bar on round weights): left alone in MuJoCo for 3 s some of them toppled or rolled
1-11 cm, every other table instance moved less than 1 cm."""
POOL_ROLES: dict[str, tuple[str, ...]] = {
    "tower_train": ("train",),
    "tower_val": ("train", "val"),
    "calibration": ("train",),
    "evaluation": ("train", "val", "test"),
    "sealed": ("train", "test"),
}
"""Seed role -> instance roles a scene of that role draws from."""
TABLE = Table(center=(0.0, 0.0, 0.375), size=(1.2, 0.8, 0.05), material="wood")
"""The table (v1's)."""

_EDGE_MARGIN = 0.05  # footprints keep this far from the table edge
_GAP = 0.03  # ... and from each other
_LINE_GAP = 0.02  # ... and from the line


@lru_cache(maxsize=1)
def table_instances() -> tuple[Instance, ...]:
    """Library instances that suit a table top, in catalogue order (see the module docstring)."""
    cat = catalogue()
    out = []
    for inst in cat.instances.values():
        if inst.category in UNSTABLE_CATEGORIES or any(g in cat.ancestors(inst.category) for g in EXCLUDED_GROUPS):
            continue
        sx, sy, sz = instance_size(inst)
        if max(sx, sy) <= MAX_FOOTPRINT and sz <= MAX_HEIGHT:
            out.append(inst)
    return tuple(out)


def instance_pool(seed_role: str) -> tuple[Instance, ...]:
    """The table instances a scene of ``seed_role`` may draw (a key of :data:`POOL_ROLES`)."""
    if seed_role not in POOL_ROLES:
        raise SimError(f"seed role {seed_role!r}: expected one of {', '.join(POOL_ROLES)}")
    roles, allowed = splits().instances, POOL_ROLES[seed_role]
    return tuple(i for i in table_instances() if roles.get(i.id) in allowed)


def scene_id_v2(seed: int) -> str:
    """The id of the v2 tabletop scene of ``seed`` (``"tabletop-v2-300007"``)."""
    return f"tabletop-v2-{int(seed):06d}"


def _phrases(inst: Instance) -> tuple[str, ...]:
    c = catalogue().categories[inst.category]
    return (f"a {inst.color} {c.name}", f"a {inst.material} {c.name}") + tuple(f"a {s}" for s in c.synonyms) + tuple(c.functions)


def generate_tabletop_v2(seed: int, *, num_objects: tuple[int, int] = NUM_OBJECTS) -> Scene:
    """The v2 tabletop scene of ``seed``: 4-12 library objects, no two with the same
    (colour, category) name, random yaw, footprints 3 cm apart and 5 cm inside the table edge,
    none on the line.

    A category is drawn uniformly among those with instances in the pool (so the long tail is
    as likely as the common kinds), then an instance of it. The seed must lie in a seed range
    of the split file; its role picks the pool (:data:`POOL_ROLES`), recorded in
    ``extras["seed_role"]``.

    Raises:
        SimError: the seed lies in no seed range of the split file, or ``num_objects`` is not
            ``1 <= lo <= hi``.
    """
    lo_n, hi_n = (int(v) for v in num_objects)
    if not 1 <= lo_n <= hi_n:
        raise SimError(f"num_objects: expected 1 <= lo <= hi, got {num_objects}")
    role = splits().seed_role(int(seed))
    if role is None:
        ranges = ", ".join(f"{k} [{a}, {b})" for k, (a, b) in splits().seeds.items())
        raise SimError(f"seed {seed}: lies in no seed range of the split file ({ranges})")
    pool = instance_pool(role)
    by_cat: dict[str, list[Instance]] = {}
    for inst in pool:
        by_cat.setdefault(inst.category, []).append(inst)
    cats = sorted(by_cat)
    rng = np.random.default_rng(int(seed))
    table = TABLE
    n = int(rng.integers(lo_n, hi_n + 1))
    placed: list[SceneObject] = []
    names: set[str] = set()
    used: set[str] = set()
    half = np.asarray(table.size[:2]) / 2
    for _ in range(60 * n):
        if len(placed) == n:
            break
        cat = cats[int(rng.integers(len(cats)))]
        inst = by_cat[cat][int(rng.integers(len(by_cat[cat])))]
        name = f"{inst.color} {inst.category}"
        if inst.id in used or name in names:
            continue
        size = tuple(float(s) for s in instance_size(inst))
        for _try in range(20):
            yaw = float(rng.uniform(-np.pi, np.pi))
            c, s = abs(np.cos(yaw)), abs(np.sin(yaw))
            ext = np.array([c * size[0] + s * size[1], s * size[0] + c * size[1]]) / 2
            lim = half - _EDGE_MARGIN - ext
            if np.any(lim <= 0):
                continue
            x, y = float(rng.uniform(-lim[0], lim[0])), float(rng.uniform(-lim[1], lim[1]))
            if abs(x) < ext[0] + _LINE_GAP:
                continue
            obj = SceneObject(
                id=f"obj{len(placed)}", name=name, category=inst.category, asset=inst.asset, color=inst.color,
                position=(x, y, table.top_z), yaw=yaw, size=size, phrases=_phrases(inst),
            )
            lo, hi = obj.footprint()
            if any(np.all(np.minimum(hi, h2) - np.maximum(lo, l2) > -_GAP) for l2, h2 in (p.footprint() for p in placed)):
                continue
            placed.append(obj)
            names.add(name)
            used.add(inst.id)
            break
    return Scene(
        id=scene_id_v2(seed), kind="tabletop", seed=int(seed), table=table, objects=tuple(placed),
        line=((0.0, -table.size[1] / 2), (0.0, table.size[1] / 2)),
        extras={"generator": "tabletop-v2", "seed_role": role},
    )
