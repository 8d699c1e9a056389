"""The one split file: which object categories, instances and scene seeds serve which role.

``scenes/splits-v1.json`` (format ``cf-splits``, version 1) fixes, for the object library
(:mod:`sim_envs.assets.library`):

* **categories**: ``train`` (the image tower may see them), ``val`` (held out from training,
  used only to choose among trained models for held-out-category generalisation) and ``test``
  (held out from everything until evaluation: the held-out categories of the open-vocabulary
  suites);
* **instances** of train categories: ``train``, ``val`` (model selection) and ``test`` (held-out
  instances of seen categories); every instance of a val or test category has that category's
  role;
* **scene seeds**: disjoint ranges for tower training views, tower validation views, score-floor
  calibration scenes and evaluation scenes (the seeds of the v2 scene generators);
* **reserved scenes**: shipped v1 scenes that chose or measured the v1 embedded tower's score floor
  (``calibration`` or ``validation``, :data:`V1_FLOOR_CALIBRATION_SCENES`,
  :data:`V1_FLOOR_VALIDATION_SCENES`); no evaluation suite uses them (no map-suite case, no
  episode on them).

The file is derived by :func:`derive_splits` from the catalogue and a few fixed choices (the
held-out categories below, picked across the taxonomy so that every held-out category keeps a
seen parent: "wine glass" is held out, "drinkware" is still seen through "mug"); instances are
ranked by a hash of their id, so the choice is stable on every machine. ``python -m
sim_envs.scenes.splits --check`` compares the shipped file with the derivation; ``--write``
rewrites it. :func:`load_splits` validates a file and refuses overlaps, naming the field.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping

from conceptfusion.errors import SimError
from conceptfusion.io_utils import atomic_write_text, read_json_document
from sim_envs.assets.library import catalogue as library_catalogue
from sim_envs.assets.library import instance_of_asset, is_library_asset
from sim_envs.scenes.episodes import SCENES_ROOT

__all__ = [
    "SPLITS_FILE", "ROLES", "SEED_ROLES", "RESERVED_ROLES", "V1_FLOOR_CALIBRATION_SCENES", "V1_FLOOR_VALIDATION_SCENES",
    "TEST_CATEGORIES", "VAL_CATEGORIES", "SPLIT_GROUPS", "Splits", "SplitError", "derive_splits", "load_splits", "splits",
    "object_group",
]

SPLITS_FILE = SCENES_ROOT / "splits-v1.json"
"""The shipped split file."""

ROLES = ("train", "val", "test")
"""Roles of categories and instances."""

SEED_ROLES = {
    "tower_train": (100_000, 150_000),
    "tower_val": (150_000, 160_000),
    "calibration": (200_000, 210_000),
    "evaluation": (300_000, 310_000),
    "sealed": (400_000, 410_000),
}
"""Scene seed ranges ``[start, stop)`` by role: views the tower trains on, views it is validated
on, scenes the score floor is calibrated on, the scenes of the first evaluation episodes (now a
second development set) and the sealed test set's scenes (``scenes/sealed-v2/``, drawn after
every choice was made; :mod:`sim_envs.scenes.sealed`)."""

TEST_CATEGORIES = (
    "wine glass", "teapot", "frying pan", "kettle", "headphones", "salt shaker", "rolling pin", "pear",
    "trophy", "lantern", "screwdriver", "stool", "bucket", "frisbee", "toy robot",
)
"""Categories held out from tower training and validation: one or two per branch of the taxonomy."""

VAL_CATEGORIES = ("jar", "remote control", "spatula", "lemon", "paintbrush", "spinning top")
"""Categories held out from training and used for model selection only."""

V1_FLOOR_CALIBRATION_SCENES = (
    "tabletop-0111", "tabletop-1448", "tabletop-2416", "tabletop-3988", "tabletop-5749", "tabletop-7474",
)
"""Shipped v1 tabletop scenes the v1 embedded tower's score floor is chosen on (every 8th shipped scene)."""

V1_FLOOR_VALIDATION_SCENES = (
    "tabletop-1055", "tabletop-1573", "tabletop-2859", "tabletop-4881", "tabletop-6667", "tabletop-8559",
)
"""Shipped v1 tabletop scenes the chosen v1 floor is measured on (every 8th from the 5th)."""

SPLIT_GROUPS = ("seen", "held_out_instance", "held_out_category", "validation")
"""How seen a scene object is (:func:`object_group`), least seen last but one: ``seen`` (an
instance the tower trained on), ``held_out_instance`` (an unseen instance of a trained category),
``held_out_category`` (a category held out from training entirely), ``validation`` (instances and
categories used for model selection)."""

RESERVED_ROLES = ("calibration", "validation")
"""Roles of reserved scenes: the v1 score floor is chosen on ``calibration`` scenes and measured on
``validation`` ones."""

_SHIPPED_KINDS = ("tabletop", "household")
"""Kinds of shipped v1 scenes (``scenes/<kind>/<kind>-NNNN.json``)."""

_MIN_INSTANCES_TO_HOLD_OUT = 3
"""A train category gives one validation and one test instance when it has at least this many."""


class SplitError(SimError):
    """A split file that is malformed or overlaps itself."""


@dataclass(frozen=True)
class Splits:
    """A validated split: role per category and per instance, seed ranges per role."""

    categories: Mapping[str, str]
    """Category name -> ``"train"``, ``"val"`` or ``"test"``."""
    instances: Mapping[str, str]
    """Instance id -> role."""
    seeds: Mapping[str, tuple[int, int]]
    """Seed role -> ``[start, stop)``."""
    reserved_scenes: Mapping[str, str]
    """Shipped v1 scene id (``"tabletop-0111"``) -> ``"calibration"`` or ``"validation"``: scenes
    that tuned or measured the v1 tower's score floor, kept out of every evaluation suite."""

    def categories_of(self, role: str) -> list[str]:
        """Category names with ``role``, sorted."""
        return sorted(c for c, r in self.categories.items() if r == _role(role))

    def instances_of(self, role: str) -> list[str]:
        """Instance ids with ``role``, sorted."""
        return sorted(i for i, r in self.instances.items() if r == _role(role))

    def seed_role(self, seed: int) -> str | None:
        """The role whose range holds ``seed`` (None: outside every range)."""
        return next((name for name, (lo, hi) in self.seeds.items() if lo <= int(seed) < hi), None)

    def seeds_of(self, role: str, n: int) -> list[int]:
        """The first ``n`` seeds of a seed role; ``SplitError`` when the range is too short."""
        if role not in self.seeds:
            raise SplitError(f"seed role {role!r}: expected one of {', '.join(self.seeds)}")
        lo, hi = self.seeds[role]
        if n > hi - lo:
            raise SplitError(f"seed role {role!r}: asked for {n} seeds, the range holds {hi - lo}")
        return list(range(lo, lo + n))

    def reserved_scene_ids(self, role: str | None = None) -> list[str]:
        """Reserved shipped scene ids (of one :data:`RESERVED_ROLES` role, or all), sorted."""
        if role is not None and role not in RESERVED_ROLES:
            raise SplitError(f"reserved role {role!r}: expected one of {', '.join(RESERVED_ROLES)}")
        return sorted(s for s, r in self.reserved_scenes.items() if role is None or r == role)

    def is_reserved_scene(self, scene: str) -> bool:
        """Whether ``scene`` is reserved: a shipped scene id (``"tabletop-0111"``) or an episode's
        scene path relative to ``scenes/`` (``"tabletop/tabletop-0111.json"``; a scene of another
        folder, such as ``calibration/tabletop-2748.json``, is not a shipped scene)."""
        scene = str(scene)
        if scene.endswith(".json"):
            folder, _, name = scene.rpartition("/")
            scene_id = name[: -len(".json")]
            return folder == scene_id.split("-")[0] and scene_id in self.reserved_scenes
        return scene in self.reserved_scenes


def _role(role: str) -> str:
    if role not in ROLES:
        raise SplitError(f"role {role!r}: expected one of {', '.join(ROLES)}")
    return role


def _rank(instance_id: str) -> str:
    return hashlib.sha256(f"cf-splits-v1:{instance_id}".encode()).hexdigest()


def derive_splits() -> dict:
    """The split file's content, derived from the library catalogue (see the module docstring)."""
    cat = library_catalogue()
    unknown = sorted(set(TEST_CATEGORIES + VAL_CATEGORIES) - set(cat.categories))
    if unknown:
        raise SplitError(f"held-out categories not in the library: {', '.join(unknown)}")
    categories = {name: "test" if name in TEST_CATEGORIES else "val" if name in VAL_CATEGORIES else "train"
                  for name in sorted(cat.categories)}
    instances = {}
    for name, role in categories.items():
        ids = sorted((i.id for i in cat.instances_of(name)), key=_rank)
        if role == "train" and len(ids) >= _MIN_INSTANCES_TO_HOLD_OUT:
            roles = ["test", "val"] + ["train"] * (len(ids) - 2)
        else:
            roles = [role] * len(ids)
        instances.update(zip(ids, roles))
    return {
        "format": "cf-splits", "version": 1,
        "categories": categories,
        "instances": dict(sorted(instances.items())),
        "seeds": {k: list(v) for k, v in SEED_ROLES.items()},
        "reserved_scenes": {**{s: "calibration" for s in V1_FLOOR_CALIBRATION_SCENES},
                            **{s: "validation" for s in V1_FLOOR_VALIDATION_SCENES}},
    }


def load_splits(path: str | Path = SPLITS_FILE) -> Splits:
    """Read and validate a split file; ``SplitError`` naming the file and the field otherwise.

    Checks: format and version; every role known; no instance in a role its category forbids
    (an instance of a val/test category must share the category's role); every instance's
    category in the file; seed ranges well formed and pairwise disjoint; every reserved scene a
    shipped v1 scene (``scenes/<kind>/<id>.json``) with a :data:`RESERVED_ROLES` role.
    """
    path = Path(path)
    data = read_json_document(path, fmt="cf-splits", version=1, what="split file", missing="no such split file", error=SplitError)
    cats, insts, seeds = data.get("categories"), data.get("instances"), data.get("seeds")
    for field, value in (("categories", cats), ("instances", insts), ("seeds", seeds)):
        if not isinstance(value, dict) or not value:
            raise SplitError(f"{path}: {field}: expected a non-empty object")
    for field, table in (("categories", cats), ("instances", insts)):
        for key, role in table.items():
            if role not in ROLES:
                raise SplitError(f"{path}: {field}.{key}: expected one of {', '.join(ROLES)}, got {role!r}")
    lib = library_catalogue()
    for iid, role in insts.items():
        inst = lib.instances.get(iid)
        if inst is None:
            raise SplitError(f"{path}: instances.{iid}: not an instance of the object library")
        crole = cats.get(inst.category)
        if crole is None:
            raise SplitError(f"{path}: instances.{iid}: its category {inst.category!r} has no role in 'categories'")
        if crole != "train" and role != crole:
            raise SplitError(f"{path}: instances.{iid}: category {inst.category!r} is {crole!r}, so its instances "
                             f"must be {crole!r} too, got {role!r} (a held-out category overlaps {role})")
    ranges = {}
    for name, rng in seeds.items():
        if (not isinstance(rng, list) or len(rng) != 2 or not all(isinstance(v, int) and not isinstance(v, bool) for v in rng)
                or not 0 <= rng[0] < rng[1]):
            raise SplitError(f"{path}: seeds.{name}: expected [start, stop) with 0 <= start < stop, got {rng!r}")
        ranges[name] = (rng[0], rng[1])
    names = sorted(ranges)
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            if ranges[a][0] < ranges[b][1] and ranges[b][0] < ranges[a][1]:
                raise SplitError(f"{path}: seeds.{a} {list(ranges[a])} and seeds.{b} {list(ranges[b])} overlap")
    reserved = _reserved_scenes(path, data.get("reserved_scenes"))
    return Splits(dict(cats), dict(insts), ranges, reserved)


def _reserved_scenes(path: Path, table) -> dict[str, str]:
    """The ``reserved_scenes`` field, validated: shipped v1 scene id -> reserved role."""
    if not isinstance(table, dict):
        raise SplitError(f"{path}: reserved_scenes: expected an object of shipped scene id -> role, got {table!r}")
    for sid, role in table.items():
        if role not in RESERVED_ROLES:
            raise SplitError(f"{path}: reserved_scenes.{sid}: expected one of {', '.join(RESERVED_ROLES)}, got {role!r}")
        kind = sid.split("-")[0]
        if kind not in _SHIPPED_KINDS or not (SCENES_ROOT / kind / f"{sid}.json").is_file():
            raise SplitError(f"{path}: reserved_scenes.{sid}: not a shipped scene "
                             f"(expected a file scenes/<{'|'.join(_SHIPPED_KINDS)}>/<id>.json)")
    return dict(table)


_CACHE: dict[str, Splits] = {}


def splits() -> Splits:
    """The shipped split (:data:`SPLITS_FILE`), loaded once."""
    if "shipped" not in _CACHE:
        _CACHE["shipped"] = load_splits(SPLITS_FILE)
    return _CACHE["shipped"]


def object_group(obj) -> str:
    """The split group (:data:`SPLIT_GROUPS`) of a scene object (anything with an ``asset``
    ``"lib:<id>"``), from the shipped split file.

    Raises:
        ValueError: the object is not a library instance (v1 primitives have no split).
    """
    asset = getattr(obj, "asset", None)
    if not isinstance(asset, str) or not is_library_asset(asset):
        raise ValueError(f"object {getattr(obj, 'id', obj)!r}: expected a library instance asset 'lib:<id>', got {asset!r}")
    inst = instance_of_asset(asset)
    sp = splits()
    cat_role, inst_role = sp.categories[inst.category], sp.instances[inst.id]
    if cat_role == "test":
        return "held_out_category"
    if cat_role == "val" or inst_role == "val":
        return "validation"
    return "seen" if inst_role == "train" else "held_out_instance"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m sim_envs.scenes.splits", description="Write or check the split file.")
    p.add_argument("--write", action="store_true", help=f"rewrite {SPLITS_FILE.name} from the catalogue")
    p.add_argument("--check", action="store_true", help="exit 1 if the shipped file differs from the derivation")
    args = p.parse_args(argv)
    text = json.dumps(derive_splits(), indent=1) + "\n"
    if args.write:
        atomic_write_text(SPLITS_FILE, text)
        load_splits(SPLITS_FILE)
        print(f"wrote {SPLITS_FILE}")
        return 0
    same = SPLITS_FILE.exists() and SPLITS_FILE.read_text() == text
    print("the split file matches the catalogue" if same else f"{SPLITS_FILE} differs from the derivation")
    return 0 if same or not args.check else 1


if __name__ == "__main__":
    sys.exit(main())
