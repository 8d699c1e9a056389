"""The declarative scene format (JSON): what a scene contains, independent of any simulator.

A file looks like::

    {"format": "cf-scene", "version": 1, "id": "tabletop-0007", "kind": "tabletop", "seed": 7,
     "table": {"center": [0, 0, 0.4], "size": [1.2, 0.8, 0.05], "material": "wood"},
     "line": {"start": [0, -0.4], "end": [0, 0.4]},
     "objects": [{"id": "obj0", "name": "red mug", "category": "mug", "asset": "mug",
                  "color": "red", "phrases": ["a coffee mug", ...], "position": [x, y, z],
                  "yaw": 0.3, "size": [0.09, 0.08, 0.10]}, ...]}

Positions are world metres (z up); an object's position is the centre of its base.

Version 2 adds household scenes (:mod:`sim_envs.scenes.household_format`): ``rooms``, ``walls`` with
door openings, ``furniture`` and, per object, an optional ``support`` (a furniture id, an
object id or ``"floor"``). A scene without these parts is still written as version 1, and
version 1 files load as before.

Loading validates everything and raises ``ValueError`` naming the problem: malformed JSON,
another format or a newer version, an unknown asset, colour, material or furniture kind, a
duplicate id, two objects on the same support whose footprints overlap, a missing support, or
an object whose base is not on its support's surface (within 1 cm).
"""

from __future__ import annotations

import json
import os
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from conceptfusion.io_utils import atomic_write_text
from sim_envs.assets.objects import ALL_ASSETS, COLORS
from sim_envs.scenes.household_format import Furniture, Room, Wall, check_supports, parse_furniture, parse_rooms, parse_vector, parse_walls

__all__ = ["SceneObject", "Table", "Scene", "Room", "Wall", "Furniture", "load_scene", "save_scene", "scene_from_json", "FORMAT", "VERSION"]

FORMAT = "cf-scene"
VERSION = 2


@dataclass(frozen=True)
class SceneObject:
    """One object in a scene."""

    id: str
    name: str
    category: str
    asset: str
    color: str
    position: tuple[float, float, float]
    yaw: float
    size: tuple[float, float, float]
    phrases: tuple[str, ...] = ()
    support: str | None = None
    """What it stands on: a furniture id, an object id or ``"floor"`` (None: not recorded)."""

    def footprint(self) -> tuple[np.ndarray, np.ndarray]:
        """World xy bounding box of the rotated footprint, (2,) lower and upper corners."""
        c, s = abs(np.cos(self.yaw)), abs(np.sin(self.yaw))
        half = np.array([c * self.size[0] + s * self.size[1], s * self.size[0] + c * self.size[1]]) / 2
        xy = np.asarray(self.position[:2], float)
        return xy - half, xy + half


@dataclass(frozen=True)
class Table:
    """The table top: a box."""

    center: tuple[float, float, float]
    size: tuple[float, float, float]
    material: str = "wood"

    @property
    def top_z(self) -> float:
        return self.center[2] + self.size[2] / 2


@dataclass(frozen=True)
class Scene:
    """A whole scene."""

    id: str
    kind: str
    seed: int
    table: Table | None
    objects: tuple[SceneObject, ...]
    line: tuple[tuple[float, float], tuple[float, float]] | None = None
    extras: dict = field(default_factory=dict)
    rooms: tuple[Room, ...] = ()
    walls: tuple[Wall, ...] = ()
    furniture: tuple[Furniture, ...] = ()

    @property
    def is_household(self) -> bool:
        """Whether the scene has rooms, walls or furniture (written as format version 2)."""
        return bool(self.rooms or self.walls or self.furniture)

    def piece(self, furniture_id: str) -> Furniture:
        """The furniture with this id; ``KeyError`` naming the valid ids otherwise."""
        for f in self.furniture:
            if f.id == furniture_id:
                return f
        raise KeyError(f"scene {self.id}: no furniture {furniture_id!r}; furniture is {[f.id for f in self.furniture]}")

    def room_at(self, xy) -> Room | None:
        """The room whose floor contains world point ``xy`` (None: outside every room)."""
        for r in self.rooms:
            if r.contains(xy):
                return r
        return None

    def object(self, object_id: str) -> SceneObject:
        """The object with this id; ``KeyError`` naming the valid ids otherwise."""
        for o in self.objects:
            if o.id == object_id:
                return o
        raise KeyError(f"scene {self.id}: no object {object_id!r}; objects are {[o.id for o in self.objects]}")

    def to_json(self) -> dict:
        d = {
            "format": FORMAT,
            "version": VERSION if self.is_household else 1,
            "id": self.id,
            "kind": self.kind,
            "seed": self.seed,
            "table": asdict(self.table) if self.table else None,
            "line": {"start": list(self.line[0]), "end": list(self.line[1])} if self.line else None,
            "objects": [_object_json(o) for o in self.objects],
        }
        if self.is_household:
            d["rooms"] = [asdict(r) for r in self.rooms]
            d["walls"] = [asdict(w) for w in self.walls]
            d["furniture"] = [asdict(f) for f in self.furniture]
        if self.extras:
            d["extras"] = self.extras
        return d


def _object_json(o: SceneObject) -> dict:
    d = asdict(o)
    if d["support"] is None:  # version 1 objects carry no support field
        del d["support"]
    return d


def scene_from_json(d: dict, *, source: str = "scene", overlap_tol: float = 0.002) -> Scene:
    """Validate a parsed scene document and build a :class:`Scene`."""
    if not isinstance(d, dict) or d.get("format") != FORMAT:
        got = d.get("format") if isinstance(d, dict) else type(d).__name__
        raise ValueError(f"{source}: expected format {FORMAT!r}, got {got!r}")
    if not isinstance(d.get("version"), int) or d["version"] > VERSION:
        raise ValueError(f"{source}: expected format version <= {VERSION}, got {d.get('version')!r}")
    table = None
    if d.get("table"):
        t = d["table"]
        table = Table(parse_vector("table.center", t.get("center"), 3), parse_vector("table.size", t.get("size"), 3), str(t.get("material", "wood")))
    objects, seen = [], set()
    for i, o in enumerate(d.get("objects") or []):
        where = f"{source}: objects[{i}]"
        if not isinstance(o, dict):
            raise ValueError(f"{where}: expected an object, got {type(o).__name__}")
        for key in ("id", "name", "category", "asset", "color", "position", "size"):
            if key not in o:
                raise ValueError(f"{where}: missing field {key!r}")
        if o["asset"] not in ALL_ASSETS:
            raise ValueError(f"{where}: unknown asset {o['asset']!r}; known assets: {sorted(ALL_ASSETS)}")
        if o["color"] not in COLORS:
            raise ValueError(f"{where}: unknown colour {o['color']!r}; known colours: {sorted(COLORS)}")
        if o["id"] in seen:
            raise ValueError(f"{where}: duplicate object id {o['id']!r}")
        seen.add(o["id"])
        size = parse_vector(f"{where}.size", o["size"], 3)
        if min(size) <= 0:
            raise ValueError(f"{where}.size: expected positive sizes, got {size}")
        objects.append(
            SceneObject(
                id=str(o["id"]), name=str(o["name"]), category=str(o["category"]), asset=str(o["asset"]),
                color=str(o["color"]), position=parse_vector(f"{where}.position", o["position"], 3),
                yaw=float(o.get("yaw", 0.0)), size=size, phrases=tuple(str(p) for p in o.get("phrases", ())),
                support=None if o.get("support") is None else str(o["support"]),
            )
        )
    rooms, walls, furniture = parse_rooms(d, source), parse_walls(d, source), parse_furniture(d, source)
    ids: set[str] = set()
    for kind, items in (("room", rooms), ("wall", walls), ("furniture", furniture), ("object", objects)):
        for it in items:
            if it.id in ids:
                raise ValueError(f"{source}: duplicate id {it.id!r} ({kind}); ids must be unique across rooms, walls, furniture and objects")
            ids.add(it.id)
    check_supports(objects, furniture, source)
    for a_i, a in enumerate(objects):  # footprints of objects on the same support and level must not overlap
        la, ha = a.footprint()
        for b in objects[a_i + 1 :]:
            lb, hb = b.footprint()
            same_level = a.support == b.support and abs(a.position[2] - b.position[2]) < 0.05
            if same_level and np.all(np.minimum(ha, hb) - np.maximum(la, lb) > overlap_tol):
                where = f" on {a.support!r}" if a.support else ""
                raise ValueError(f"{source}: objects {a.id!r} ({a.name}) and {b.id!r} ({b.name}) overlap{where}")
    line = None
    if d.get("line"):
        line = (parse_vector("line.start", d["line"].get("start"), 2), parse_vector("line.end", d["line"].get("end"), 2))
    return Scene(
        str(d.get("id", "")), str(d.get("kind", "")), int(d.get("seed", 0)), table, tuple(objects), line, d.get("extras", {}),
        rooms, walls, furniture,
    )


def load_scene(path: str | os.PathLike) -> Scene:
    """Read and validate a scene file."""
    p = Path(path)
    try:
        doc = json.loads(p.read_text())
    except json.JSONDecodeError as exc:
        raise ValueError(f"{p}: malformed JSON at line {exc.lineno}: {exc.msg}") from exc
    return scene_from_json(doc, source=str(p))


def save_scene(scene: Scene, path: str | os.PathLike) -> Path:
    """Write a scene file atomically."""
    return atomic_write_text(path, json.dumps(scene.to_json(), indent=1))
