"""The catalogue: every category and instance of the library, drawn deterministically.

Instance ``k`` of a category is drawn from numbers hashed out of ``(category, k, field)`` with
SHA-256, not from a random generator, so the catalogue is the same on every run, machine and
numpy version; :func:`catalogue_hash` pins it. Instance ids read ``<category slug>-<k:03d>``
("wine_glass-003"); named meshes of ``pybullet_data`` read ``pb-<kind>`` or, when painted in
several colours, ``pb-<kind>-<k>``. A scene uses an instance as the asset ``"lib:<id>"``.

The catalogue holds no meshes: :mod:`~sim_envs.assets.library.export` builds and caches them.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from functools import lru_cache
from typing import Iterable

from conceptfusion.errors import SimError, UnknownKeyError
from conceptfusion.names import did_you_mean, unknown_name_error
from sim_envs.assets.library.catalogue_home import HOME_CATEGORIES, NAMED_CATEGORIES
from sim_envs.assets.library.catalogue_kitchen import GROUPS, KITCHEN_CATEGORIES
from sim_envs.assets.library.named import NAMED, NamedMesh
from sim_envs.assets.library.palette import MATERIALS, PALETTE
from sim_envs.assets.library.shapes import SHAPES
from sim_envs.assets.library.taxonomy import LICENCES, Category, Group, ancestors, check_taxonomy
from sim_envs.assets.meshes import MeshKind

__all__ = [
    "Instance", "Catalogue", "LIB_PREFIX", "draw_instances", "named_instances", "build_catalogue", "catalogue",
    "get_instance", "get_category", "is_library_asset", "instance_of_asset", "scene_instance", "catalogue_hash",
]

LIB_PREFIX = "lib:"
"""Scene asset names of library instances start with this ("lib:mug-003")."""


@dataclass(frozen=True)
class Instance:
    """One object of the library."""

    id: str
    """Unique id ("mug-003", "pb-duck")."""
    category: str
    """Its category's name."""
    variant: str
    """Procedural shape variant (a key of ``shapes.SHAPES``), or ``"pybullet"`` for a named mesh."""
    params: tuple[tuple[str, float], ...]
    """The variant's parameters, sorted by name (empty for named meshes)."""
    material: str
    """What it is made of (a key of ``palette.MATERIALS``)."""
    color: str
    """Its colour (a key of ``palette.PALETTE``)."""
    scale: float
    """Length of its longest bounding-box side (metres), within its category's size range."""
    source: str
    """Where it comes from ("procedural (sim_envs.assets.library)", "pybullet_data (bullet3)")."""
    licence: str
    """Licence id (a key of ``taxonomy.LICENCES``)."""
    mesh: MeshKind | None = None
    """The ``pybullet_data`` mesh of a named instance; None for procedural ones."""

    @property
    def asset(self) -> str:
        """Its scene asset name, ``"lib:<id>"``."""
        return LIB_PREFIX + self.id

    def param_dict(self) -> dict[str, float]:
        """:attr:`params` as a dict."""
        return dict(self.params)

    def record(self) -> dict:
        """A JSON-ready description (what the catalogue hash covers)."""
        d = {"id": self.id, "category": self.category, "variant": self.variant, "params": [list(p) for p in self.params],
             "material": self.material, "color": self.color, "scale": self.scale, "source": self.source, "licence": self.licence}
        if self.mesh is not None:
            d["mesh"] = {"file": self.mesh.mesh, "texture": self.mesh.texture, "up_axis": self.mesh.up_axis}
        return d


def _unit(*key) -> float:
    """A number in [0, 1) fixed by ``key`` (SHA-256; the same everywhere)."""
    digest = hashlib.sha256("|".join(str(k) for k in key).encode()).digest()
    return int.from_bytes(digest[:8], "big") / 2.0**64


def draw_instances(c: Category) -> list[Instance]:
    """The ``c.count`` procedural instances of category ``c``.

    Instance ``k`` takes variant ``k mod len(variants)`` (so every variant appears), colour ``k``
    of a fixed shuffle of the category's colours, a material leaning to the first listed, its
    parameters and its scale drawn uniformly within their ranges (rounded to 0.1 mm / 1e-4).
    """
    colors = sorted(c.colors, key=lambda col: _unit(c.name, "colour order", col))
    out = []
    for k in range(c.count):
        variant = c.variants[k % len(c.variants)]
        ranges = SHAPES[variant].params if variant in SHAPES else {}
        params = []
        for name, (lo, hi) in sorted(ranges.items()):
            u = _unit(c.name, k, "param", name)
            if isinstance(lo, int) and isinstance(hi, int):
                params.append((name, float(lo + min(int(u * (hi - lo + 1)), hi - lo))))
            else:
                params.append((name, round(lo + u * (hi - lo), 4)))
        material = c.materials[int(_unit(c.name, k, "material") ** 1.6 * len(c.materials))]
        lo, hi = c.size_range
        scale = round(lo + _unit(c.name, k, "scale") * (hi - lo), 4)
        out.append(Instance(f"{c.slug}-{k:03d}", c.name, variant, tuple(params), material, colors[k % len(colors)],
                            scale, c.source, c.licence))
    return out


def named_instances(named: Iterable[NamedMesh] = NAMED) -> list[Instance]:
    """Instances of the named ``pybullet_data`` meshes (one per colour when painted)."""
    out = []
    for n in named:
        spec = n.mesh_kind
        for k, color in enumerate(n.colors):
            iid = f"pb-{n.kind}" if len(n.colors) == 1 else f"pb-{n.kind}-{k}"
            out.append(Instance(iid, n.category, "pybullet", (), n.material, color, n.scale, "pybullet_data (bullet3)", n.licence, spec))
    return out


@dataclass(frozen=True)
class Catalogue:
    """A validated set of groups, categories and instances (lookups by name / id)."""

    groups: dict[str, Group]
    """Inner nodes of the taxonomy by name."""
    categories: dict[str, Category]
    """Categories by name."""
    instances: dict[str, Instance]
    """Instances by id, in catalogue order."""

    def ancestors(self, name: str) -> tuple[str, ...]:
        """Every group above a category or group, nearest first."""
        return ancestors(name, {**self.groups, **self.categories})

    def instances_of(self, category: str) -> list[Instance]:
        """The instances of one category."""
        return [i for i in self.instances.values() if i.category == category]

    def records(self) -> dict:
        """The whole catalogue as JSON-ready data (licences, groups, categories, instances)."""
        return {
            "licences": {k: vars(v) for k, v in sorted(LICENCES.items())},
            "groups": [vars(g) for g in self.groups.values()],
            "categories": [{**vars(c), "ancestors": list(self.ancestors(c.name))} for c in self.categories.values()],
            "instances": [i.record() for i in self.instances.values()],
        }


def build_catalogue(
    groups: Iterable[Group], categories: Iterable[Category], instances: Iterable[Instance] | None = None,
    *, source: str = "library catalogue",
) -> Catalogue:
    """Validate and index a catalogue; ``instances`` None draws the procedural instances of
    ``categories`` and adds the named meshes.

    Raises:
        SimError: naming ``source`` and the field at fault: anything :func:`check_taxonomy`
            rejects, an unknown shape variant, a duplicate instance id, an instance naming an
            unknown category, material, colour or licence, or a scale outside its category's
            size range.
    """
    groups, categories = list(groups), list(categories)
    check_taxonomy(groups, categories, materials=MATERIALS, colors=PALETTE, source=source)
    cats = {c.name: c for c in categories}
    for c in categories:
        for v in c.variants:
            if v not in SHAPES:
                raise SimError(f"{source}: category {c.name!r}.variants: unknown shape variant {v!r}" + did_you_mean(v, SHAPES))
    if instances is None:
        instances = [i for c in categories for i in draw_instances(c)] + named_instances()
    by_id: dict[str, Instance] = {}
    for inst in instances:
        where = f"{source}: instance {inst.id!r}"
        if inst.id in by_id:
            raise SimError(f"{where}.id: duplicate instance id")
        if inst.category not in cats:
            raise SimError(f"{where}.category: unknown category {inst.category!r}" + did_you_mean(inst.category, cats))
        for field, table in (("material", MATERIALS), ("color", PALETTE), ("licence", LICENCES)):
            value = getattr(inst, field)
            if value not in table:
                raise SimError(f"{where}.{field}: unknown {field} {value!r}" + did_you_mean(value, table))
        if inst.variant != "pybullet" and inst.variant not in SHAPES:
            raise SimError(f"{where}.variant: unknown shape variant {inst.variant!r}" + did_you_mean(inst.variant, SHAPES))
        if (inst.variant == "pybullet") != (inst.mesh is not None):
            raise SimError(f"{where}.mesh: a named mesh instance needs variant 'pybullet' and a mesh, a procedural one neither")
        lo, hi = cats[inst.category].size_range
        if not lo - 1e-9 <= inst.scale <= hi + 1e-9:
            raise SimError(f"{where}.scale: {inst.scale} m is outside category {inst.category!r}'s size range {lo}-{hi} m")
        by_id[inst.id] = inst
    return Catalogue({g.name: g for g in groups}, cats, by_id)


@lru_cache(maxsize=1)
def catalogue() -> Catalogue:
    """The library's catalogue (built once per process)."""
    return build_catalogue(GROUPS, KITCHEN_CATEGORIES + HOME_CATEGORIES + NAMED_CATEGORIES)


def is_library_asset(asset: str) -> bool:
    """Whether a scene asset name refers to a library instance (``"lib:..."``)."""
    return isinstance(asset, str) and asset.startswith(LIB_PREFIX)


def get_instance(instance_id: str) -> Instance:
    """The instance with this id (``"mug-003"``; a ``"lib:"`` prefix is accepted).

    Raises:
        UnknownKeyError: no such instance (naming the nearest ids).
    """
    key = instance_id[len(LIB_PREFIX):] if is_library_asset(instance_id) else instance_id
    inst = catalogue().instances.get(key)
    if inst is None:
        raise unknown_name_error("library instance", key, catalogue().instances, cutoff=0.5, listing="", error=UnknownKeyError)
    return inst


def instance_of_asset(asset: str) -> Instance:
    """The instance a ``"lib:<id>"`` scene asset names (``UnknownKeyError`` if none)."""
    if not is_library_asset(asset):
        raise SimError(f"expected a library asset name 'lib:<instance id>', got {asset!r}")
    return get_instance(asset)


def scene_instance(asset, color, where: str, *, error: type[SimError] = SimError) -> Instance:
    """The instance a scene object's ``asset`` names, checked against its ``color``.

    Raises:
        ``error`` (a :class:`SimError`) naming ``where`` and the field: ``.asset`` for a name
        that is no ``"lib:<id>"`` of the catalogue (with the nearest ids), ``.color`` for a
        colour other than the instance's own (a library instance has one colour).
    """
    if not is_library_asset(asset):
        raise error(f"{where}.asset: expected a library asset 'lib:<instance id>', got {asset!r}")
    key = asset[len(LIB_PREFIX):]
    inst = catalogue().instances.get(key)
    if inst is None:
        raise error(f"{where}.asset: unknown library instance {key!r}" + did_you_mean(key, catalogue().instances, cutoff=0.6))
    if color != inst.color:
        raise error(f"{where}.color: library instance {key!r} is {inst.color!r}, got {color!r}")
    return inst


def get_category(name: str) -> Category:
    """The category called ``name`` (``UnknownKeyError`` naming the nearest ones)."""
    cats = catalogue().categories
    if name not in cats:
        raise unknown_name_error("library category", name, cats, cutoff=0.6, listing="", error=UnknownKeyError)
    return cats[name]


def catalogue_hash() -> str:
    """SHA-256 of the catalogue's records (JSON, sorted keys): changes whenever any category,
    instance or licence does."""
    text = json.dumps(catalogue().records(), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()
