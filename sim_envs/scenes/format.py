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

Loading validates everything, field by field, and raises
:class:`~conceptfusion.errors.SceneFormatError` (a ``ValueError``) naming the file and the field:
a file that is not UTF-8 or malformed JSON, another format or a newer version, a field of the
wrong type (a number where a string is expected is refused, not converted), a NaN or infinite
number, a number of magnitude above :data:`~sim_envs.scenes.household_format.MAX_MAGNITUDE`
(10 km: no scene spans more), a non-positive size, an unknown asset, colour, material or furniture kind, a duplicate
id, two objects on the same support whose footprints overlap, a missing support, an object
whose base is not on its support's surface (within 1 cm), or, in a scene with a table, an
object without a support whose centre is off the table top or whose base is not on it (1 cm).
A missing file raises :class:`~conceptfusion.errors.MissingFileError`.
"""

from __future__ import annotations

import json
import os
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path

import numpy as np

from conceptfusion.io_utils import MAX_SCENE_BYTES, atomic_write_text, read_text_file
from conceptfusion.strict_json import loads_strict
from sim_envs.assets.objects import ALL_ASSETS, COLORS
from sim_envs.assets.library.catalogue import is_library_asset, scene_instance
from conceptfusion.errors import SceneFormatError
from sim_envs.scenes.household_format import (
    Furniture, Room, Wall, check_fields, check_supports, parse_furniture, parse_list, parse_material, parse_number, parse_phrases, parse_rooms,
    parse_text, parse_vector, parse_walls,
)
from sim_envs.scenes.overlaps import overlapping_pairs
from sim_envs.scenes.household_shapes import WALL_OVERLAP_TOL, furniture_in_walls

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

    def floor_bounds(self) -> tuple[tuple[float, float], tuple[float, float]] | None:
        """The apartment's bounds: lower and upper xy corners of the box around every room's
        floor (None: a scene without rooms)."""
        if not self.rooms:
            return None
        lows, highs = [r.floor[0] for r in self.rooms], [r.floor[1] for r in self.rooms]
        return ((min(p[0] for p in lows), min(p[1] for p in lows)), (max(p[0] for p in highs), max(p[1] for p in highs)))

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


_OBJECT_FIELDS = tuple(f.name for f in fields(SceneObject))
_SCENE_FIELDS = ("format", "version", "id", "kind", "seed", "table", "line", "objects", "rooms", "walls", "furniture", "extras")


def _parse_table(t, source: str) -> Table:
    where = f"{source}: table"
    if not isinstance(t, dict):
        raise SceneFormatError(f"{where}: expected an object {{center, size, material}} or null, got {type(t).__name__} {t!r}")
    check_fields(where, t, ("center", "size"), ("center", "size", "material"))
    size = parse_vector(f"{where}.size", t["size"], 3)
    if min(size) <= 0:
        raise SceneFormatError(f"{where}.size: expected positive sizes, got {list(size)}")
    return Table(parse_vector(f"{where}.center", t["center"], 3), size, parse_material(f"{where}.material", t.get("material", "wood")))


def _parse_line(ln, source: str) -> tuple[tuple[float, float], tuple[float, float]]:
    where = f"{source}: line"
    if not isinstance(ln, dict):
        raise SceneFormatError(f"{where}: expected an object {{start, end}} or null, got {type(ln).__name__} {ln!r}")
    check_fields(where, ln, ("start", "end"), ("start", "end"))
    start, end = parse_vector(f"{where}.start", ln.get("start"), 2), parse_vector(f"{where}.end", ln.get("end"), 2)
    if start == end:
        raise SceneFormatError(f"{where}: start and end coincide at {list(start)}")
    return start, end


def _parse_object(o, where: str) -> SceneObject:
    if not isinstance(o, dict):
        raise SceneFormatError(f"{where}: expected an object, got {type(o).__name__}")
    check_fields(where, o, ("id", "name", "category", "asset", "color", "position", "size"), _OBJECT_FIELDS)
    oid = parse_text(f"{where}.id", o["id"])
    if is_library_asset(o["asset"]):  # "lib:<id>": an object library instance, in its own colour
        scene_instance(o["asset"], o["color"], where, error=SceneFormatError)
    elif not isinstance(o["asset"], str) or o["asset"] not in ALL_ASSETS:
        raise SceneFormatError(f"{where}.asset: unknown asset {o['asset']!r}; known assets: {sorted(ALL_ASSETS)}")
    elif not isinstance(o["color"], str) or o["color"] not in COLORS:
        raise SceneFormatError(f"{where}.color: unknown colour {o['color']!r}; known colours: {sorted(COLORS)}")
    size = parse_vector(f"{where}.size", o["size"], 3)
    if min(size) <= 0:
        raise SceneFormatError(f"{where}.size: expected positive sizes, got {list(size)}")
    support = o.get("support")
    return SceneObject(
        id=oid, name=parse_text(f"{where}.name", o["name"]), category=parse_text(f"{where}.category", o["category"]),
        asset=o["asset"], color=o["color"], position=parse_vector(f"{where}.position", o["position"], 3),
        yaw=parse_number(f"{where}.yaw", o.get("yaw", 0.0)), size=size,
        phrases=parse_phrases(f"{where}.phrases", o.get("phrases")),
        support=None if support is None else parse_text(f"{where}.support", support),
    )


def _check_on_table(objects, table: Table, source: str, tol: float) -> None:
    """Objects without a recorded support stand on the table top: centre over it, base on it."""
    (cx, cy, _), (sx, sy, _) = table.center, table.size
    for i, o in enumerate(objects):
        if o.support is not None:
            continue
        x, y, z = o.position
        where = f"{source}: objects[{i}] ({o.id!r}, {o.name})"
        if abs(x - cx) > sx / 2 + tol or abs(y - cy) > sy / 2 + tol:
            raise SceneFormatError(
                f"{where}: off the table: its centre ({x:.3f}, {y:.3f}) is outside the table top "
                f"x in [{cx - sx / 2:.3f}, {cx + sx / 2:.3f}], y in [{cy - sy / 2:.3f}, {cy + sy / 2:.3f}] (tolerance {tol} m)"
            )
        if abs(z - table.top_z) > tol:
            raise SceneFormatError(
                f"{where}: floats: base at z={z:.3f}, but the table top is at z={table.top_z:.3f} (tolerance {tol} m)"
            )


def scene_from_json(d: dict, *, source: str = "scene", overlap_tol: float = 0.002, support_tol: float = 0.01) -> Scene:
    """Validate a parsed scene document and build a :class:`Scene`.

    Every field is checked for its type (no conversion: ``"id": 5`` is refused, not read as
    ``"5"``), finiteness and range; an error is a :class:`~conceptfusion.errors.SceneFormatError`
    (a ``ValueError``) whose message starts with ``source`` and names the field
    (``objects[2].yaw``). Objects with a ``support`` must rest on it (within ``support_tol``);
    objects without one, in a scene with a table, must stand on the table top (centre over it,
    base within ``support_tol`` of its height). No piece of furniture may reach into a wall
    (:func:`~sim_envs.scenes.household_shapes.furniture_in_walls`).
    """
    if not isinstance(d, dict) or d.get("format") != FORMAT:
        got = d.get("format") if isinstance(d, dict) else type(d).__name__
        raise SceneFormatError(f"{source}: expected format {FORMAT!r}, got {got!r}")
    version = d.get("version")
    if isinstance(version, bool) or not isinstance(version, int) or version < 1:
        raise SceneFormatError(f"{source}: version: expected an integer format version >= 1, got {version!r}")
    if version > VERSION:
        raise SceneFormatError(f"{source}: expected format version <= {VERSION}, got {version!r}")
    check_fields(source, d, (), _SCENE_FIELDS)
    scene_id = parse_text(f"{source}: id", d.get("id", ""), allow_empty=True)
    kind = parse_text(f"{source}: kind", d.get("kind", ""), allow_empty=True)
    seed = d.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int):
        raise SceneFormatError(f"{source}: seed: expected an integer, got {seed!r}")
    extras = d.get("extras", {})
    if not isinstance(extras, dict):
        raise SceneFormatError(f"{source}: extras: expected an object, got {type(extras).__name__} {extras!r}")
    table = None if d.get("table") is None else _parse_table(d["table"], source)
    line = None if d.get("line") is None else _parse_line(d["line"], source)
    objects, seen = [], set()
    for i, o in enumerate(parse_list(f"{source}: objects", d.get("objects"))):
        where = f"{source}: objects[{i}]"
        obj = _parse_object(o, where)
        if obj.id in seen:
            raise SceneFormatError(f"{where}: duplicate object id {obj.id!r}")
        seen.add(obj.id)
        objects.append(obj)
    rooms, walls, furniture = parse_rooms(d, source), parse_walls(d, source), parse_furniture(d, source)
    ids: set[str] = set()
    for kind_name, items in (("room", rooms), ("wall", walls), ("furniture", furniture), ("object", objects)):
        for it in items:
            if it.id in ids:
                raise SceneFormatError(f"{source}: duplicate id {it.id!r} ({kind_name}); ids must be unique across rooms, walls, furniture and objects")
            ids.add(it.id)
    in_walls = furniture_in_walls(walls, furniture)
    if in_walls:
        j, wall_id, depth = in_walls[0]
        f = furniture[j]
        more = f" ({len(in_walls) - 1} more piece(s) in walls)" if len(in_walls) > 1 else ""
        raise SceneFormatError(
            f"{source}: furniture[{j}] ({f.id!r}, {f.name}): its footprint reaches {depth:.3f} m into wall {wall_id!r}; "
            f"expected at most {WALL_OVERLAP_TOL} m (move it out of the wall){more}"
        )
    check_supports(objects, furniture, source, tol=support_tol)
    if table is not None:
        _check_on_table(objects, table, source, support_tol)
    pairs = overlapping_pairs(objects, overlap_tol)  # objects on the same support and level must not overlap
    if pairs:
        a, b = objects[pairs[0][0]], objects[pairs[0][1]]
        where = f" on {a.support!r}" if a.support else ""
        more = f" ({len(pairs) - 1} more overlapping pair(s))" if len(pairs) > 1 else ""
        raise SceneFormatError(f"{source}: objects {a.id!r} ({a.name}) and {b.id!r} ({b.name}) overlap{where}{more}")
    return Scene(scene_id, kind, seed, table, tuple(objects), line, extras, rooms, walls, furniture)


def load_scene(path: str | os.PathLike) -> Scene:
    """Read and validate a scene file.

    Raises :class:`~conceptfusion.errors.MissingFileError` (a ``FileNotFoundError``) when there
    is no such file, and :class:`~conceptfusion.errors.SceneFormatError` (a ``ValueError``)
    naming the file, and the line or field, for a path that is not a regular file (a folder, a
    FIFO, a device; symlinks are followed) or is larger than
    :data:`~conceptfusion.io_utils.MAX_SCENE_BYTES`, a file that is not UTF-8 JSON text, JSON
    with a key twice in one object, nested too deeply or with a huge integer
    (:func:`~conceptfusion.strict_json.loads_strict`), or not a valid scene (see
    :func:`scene_from_json`).
    """
    p = Path(path)
    text = read_text_file(p, "scene file", SceneFormatError, max_bytes=MAX_SCENE_BYTES)
    try:
        doc = loads_strict(text, source=str(p), error=SceneFormatError)
    except json.JSONDecodeError as exc:
        raise SceneFormatError(f"{p}: malformed JSON at line {exc.lineno}: {exc.msg}") from exc
    except RecursionError:
        raise SceneFormatError(f"{p}: malformed JSON: nested too deeply") from None
    return scene_from_json(doc, source=str(p))


def save_scene(scene: Scene, path: str | os.PathLike) -> Path:
    """Write a scene file atomically."""
    return atomic_write_text(path, json.dumps(scene.to_json(), indent=1))
