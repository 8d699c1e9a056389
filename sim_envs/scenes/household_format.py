"""The household parts of the scene format: rooms, walls with door openings, furniture, supports.

JSON shapes (all lengths world metres, z up)::

    "rooms": [{"id": "room0", "name": "kitchen", "floor": [[x0, y0], [x1, y1]],
               "floor_material": "tile", "wall_material": "plaster_white"}, ...],
    "walls": [{"id": "wall0", "start": [x, y], "end": [x, y], "thickness": 0.1, "height": 2.5,
               "materials": ["plaster_white", "plaster_beige"], "doors": [[offset, width], ...]}],
    "furniture": [{"id": "f0", "name": "wooden counter", "category": "counter",
                   "position": [x, y, z], "yaw": 0.0, "size": [w, d, h], "material": "wood",
                   "phrases": [...], "shelf_heights": [...]}, ...]

A wall's ``materials`` are its left and right faces seen walking from ``start`` to ``end``; a
door is a gap ``[offset, width]`` along the wall from ``start``. A piece of furniture's
``position`` is the centre of its footprint on the floor; its shape and support surfaces come
from :data:`sim_envs.assets.furniture.FURNITURE`. An object's ``support`` names what it stands on: a
furniture id, an object id (inside an open container such as a bowl, or on top of another
object) or ``"floor"``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from functools import lru_cache

import numpy as np

from conceptfusion.errors import SceneFormatError
from conceptfusion.names import did_you_mean
from sim_envs.assets.furniture import FURNITURE, MATERIALS, Surface
from sim_envs.assets.library.catalogue import get_instance, is_library_asset
from sim_envs.assets.library.export import instance_parts

__all__ = [
    "parse_vector", "parse_number", "parse_text", "parse_list", "parse_phrases", "parse_material",
    "check_fields", "MAX_MAGNITUDE",
    "Room", "Wall", "Furniture", "CONTAINER_FLOOR", "parse_rooms", "parse_walls", "parse_furniture",
    "check_supports", "support_surface_z", "LIBRARY_CONTAINERS", "container_floor",
]

MAX_MAGNITUDE = 1.0e4
"""Largest absolute value of any number in a scene (coordinates, sizes, yaws, door offsets):
10 km in metres. No scene spans more; ``1e300`` is a corrupt file, and arithmetic on it
overflows (footprints, occupancy grids) far from where the number was read."""

CONTAINER_FLOOR: dict[str, float] = {"bowl": 0.01}
"""Object assets that are open containers: height of the inner floor above the base (metres)."""

LIBRARY_CONTAINERS: frozenset[str] = frozenset({"bowl", "basket", "crate", "tray"})
"""Object library categories whose instances are open containers that things are put inside."""


@lru_cache(maxsize=None)
def _library_floor_fraction(instance_id: str) -> float | None:
    """Inner floor height of a library container as a fraction of its height (None: no floor).

    From the procedural parts: the inner floor of every open vessel part (its lowest point plus
    its ``floor``) and the top of every solid part that rests at the bottom and covers the
    centre (an open box's floor slab, a pedestal); the highest of these, over the instance's
    whole height (what the exported mesh is normalised by).
    """
    inst = get_instance(instance_id)
    if inst.category not in LIBRARY_CONTAINERS or inst.mesh is not None:
        return None
    parts = instance_parts(inst)
    z = [p.mesh.vertices[:, 2] for p in parts]
    z0, z1 = min(v.min() for v in z), max(v.max() for v in z)
    tops = []
    for p in parts:
        v = p.mesh.vertices
        if p.collision == "hollow":
            tops.append(v[:, 2].min() + p.floor)
        elif p.collision == "hull" and v[:, 2].min() <= z0 + 1e-6 and np.all(v[:, :2].min(0) <= 0) and np.all(v[:, :2].max(0) >= 0):
            tops.append(v[:, 2].max())
    if not tops or z1 <= z0:
        return None
    return float((max(tops) - z0) / (z1 - z0))


def container_floor(asset: str, size) -> float | None:
    """Height (metres) of an open container's inner floor above its base, for an object of this
    ``asset`` and ``size`` (x, y, z); None when the asset is no open container.

    Covers the primitive assets of :data:`CONTAINER_FLOOR` and the library instances
    (``"lib:<id>"``) of the :data:`LIBRARY_CONTAINERS` categories.
    """
    if asset in CONTAINER_FLOOR:
        return CONTAINER_FLOOR[asset]
    if is_library_asset(asset):
        frac = _library_floor_fraction(get_instance(asset).id)
        return None if frac is None else frac * float(size[2])
    return None


@dataclass(frozen=True)
class Room:
    """A room: a named floor rectangle."""

    id: str
    name: str
    floor: tuple[tuple[float, float], tuple[float, float]]
    floor_material: str = "parquet"
    wall_material: str = "plaster_white"

    def contains(self, xy, tol: float = 0.0) -> bool:
        (x0, y0), (x1, y1) = self.floor
        return x0 - tol <= xy[0] <= x1 + tol and y0 - tol <= xy[1] <= y1 + tol

    @property
    def center(self) -> tuple[float, float]:
        (x0, y0), (x1, y1) = self.floor
        return ((x0 + x1) / 2, (y0 + y1) / 2)


@dataclass(frozen=True)
class Wall:
    """A straight wall segment; doors are gaps ``(offset from start, width)``."""

    id: str
    start: tuple[float, float]
    end: tuple[float, float]
    thickness: float = 0.1
    height: float = 2.5
    materials: tuple[str, str] = ("plaster_white", "plaster_white")
    doors: tuple[tuple[float, float], ...] = ()

    @property
    def length(self) -> float:
        return math.dist(self.start, self.end)

    def solid_spans(self) -> list[tuple[float, float]]:
        """(from, to) offsets along the wall of the solid parts between doors."""
        spans, at = [], 0.0
        for off, width in sorted(self.doors):
            if off > at:
                spans.append((at, off))
            at = off + width
        if at < self.length:
            spans.append((at, self.length))
        return spans


@dataclass(frozen=True)
class Furniture:
    """A piece of furniture: a kind from :data:`~sim_envs.assets.furniture.FURNITURE`, posed and sized."""

    id: str
    name: str
    category: str
    position: tuple[float, float, float]
    yaw: float
    size: tuple[float, float, float]
    material: str
    phrases: tuple[str, ...] = ()
    shelf_heights: tuple[float, ...] = ()

    def surfaces(self) -> list[Surface]:
        """Support surfaces in the piece's frame (``z`` relative to its base)."""
        return FURNITURE[self.category].surfaces(self.size, self.shelf_heights)

    def to_local(self, xy) -> np.ndarray:
        """World xy -> the piece's frame."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        dx, dy = xy[0] - self.position[0], xy[1] - self.position[1]
        return np.array([c * dx + s * dy, -s * dx + c * dy])

    def to_world(self, xy_local) -> np.ndarray:
        """The piece's frame -> world xy."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        x, y = xy_local
        return np.array([self.position[0] + c * x - s * y, self.position[1] + s * x + c * y])

    def footprint(self) -> tuple[np.ndarray, np.ndarray]:
        """World xy bounding box of the rotated footprint, (2,) lower and upper corners."""
        c, s = abs(math.cos(self.yaw)), abs(math.sin(self.yaw))
        half = np.array([c * self.size[0] + s * self.size[1], s * self.size[0] + c * self.size[1]]) / 2
        xy = np.asarray(self.position[:2], float)
        return xy - half, xy + half


_FIELDS = {cls: tuple(f.name for f in fields(cls)) for cls in (Room, Wall, Furniture)}


def _is_number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def parse_vector(name: str, value, n: int) -> tuple[float, ...]:
    """``value`` as ``n`` finite floats of magnitude at most :data:`MAX_MAGNITUDE`;
    :class:`SceneFormatError` naming the field ``name`` otherwise.

    Only a JSON list of numbers is accepted: a string, a bool or a number in quotes is refused
    rather than converted.
    """
    if not isinstance(value, (list, tuple)) or not all(_is_number(x) for x in value):
        raise SceneFormatError(f"{name}: expected a list of {n} numbers, got {value!r}")
    v = tuple(float(x) for x in value)
    if len(v) != n or not all(math.isfinite(x) for x in v):
        raise SceneFormatError(f"{name}: expected {n} finite numbers, got {value!r}")
    if any(abs(x) > MAX_MAGNITUDE for x in v):
        raise SceneFormatError(f"{name}: expected {n} numbers within +-{MAX_MAGNITUDE:g} (metres), got {list(v)!r}")
    return v


def parse_number(name: str, value, *, positive: bool = False) -> float:
    """``value`` as one finite float of magnitude at most :data:`MAX_MAGNITUDE` (``positive``: also
    > 0); :class:`SceneFormatError` naming ``name``."""
    if not _is_number(value) or not math.isfinite(value):
        raise SceneFormatError(f"{name}: expected a finite number, got {value!r}")
    if abs(value) > MAX_MAGNITUDE:
        raise SceneFormatError(f"{name}: expected a number within +-{MAX_MAGNITUDE:g}, got {value!r}")
    if positive and not value > 0:
        raise SceneFormatError(f"{name}: expected a positive number, got {value!r}")
    return float(value)


def parse_text(name: str, value, *, allow_empty: bool = False) -> str:
    """``value`` if it is a string (non-empty unless ``allow_empty``); :class:`SceneFormatError` naming ``name``.

    Numbers are refused rather than converted (``"id": 5`` is not the id ``"5"``).
    """
    if not isinstance(value, str) or (not value and not allow_empty):
        raise SceneFormatError(f"{name}: expected a {'' if allow_empty else 'non-empty '}string, got {value!r}")
    return value


def parse_list(name: str, value) -> list:
    """``value`` as a list if it is a JSON list (or a tuple, as :meth:`Scene.to_json` leaves them;
    ``None`` or absent: empty); :class:`SceneFormatError` naming ``name`` otherwise."""
    if value is None:
        return []
    if not isinstance(value, (list, tuple)):
        raise SceneFormatError(f"{name}: expected a list, got {type(value).__name__} {value!r}")
    return list(value)


def parse_phrases(name: str, value) -> tuple[str, ...]:
    """A list of strings (absent: empty), as a tuple."""
    return tuple(parse_text(f"{name}[{k}]", x) for k, x in enumerate(parse_list(name, value)))


def parse_material(name: str, value) -> str:
    """One of :data:`~sim_envs.assets.furniture.MATERIALS`; the message names the known ones."""
    if not isinstance(value, str) or value not in MATERIALS:
        raise SceneFormatError(f"{name}: unknown material {value!r}; known materials: {list(MATERIALS)}")
    return value


def check_fields(where: str, d: dict, required: tuple[str, ...], allowed) -> None:
    """Every ``required`` key is in ``d`` and every key of ``d`` is ``allowed``; a
    :class:`SceneFormatError` naming the field (and the nearest allowed names) otherwise, so a
    typo (``"yaww"``) is not silently read as the default."""
    for k in required:
        if k not in d:
            raise SceneFormatError(f"{where}: missing field {k!r}")
    for k in d:
        if k not in allowed:
            raise SceneFormatError(f"{where}: unknown field {k!r}{did_you_mean(k, allowed)} (fields: {', '.join(allowed)})")


def _entries(d: dict, key: str, source: str, required: tuple[str, ...], allowed: tuple[str, ...]):
    for i, e in enumerate(parse_list(f"{source}: {key}", d.get(key))):
        where = f"{source}: {key}[{i}]"
        if not isinstance(e, dict):
            raise SceneFormatError(f"{where}: expected an object, got {type(e).__name__}")
        check_fields(where, e, required, allowed)
        yield where, e


def parse_rooms(d: dict, source: str) -> tuple[Room, ...]:
    """Validated rooms of a scene document (empty when it has none)."""
    rooms = []
    for where, r in _entries(d, "rooms", source, ("id", "name", "floor"), _FIELDS[Room]):
        fl = r["floor"]
        if not isinstance(fl, (list, tuple)) or len(fl) != 2:
            raise SceneFormatError(f"{where}.floor: expected [[x0, y0], [x1, y1]], got {fl!r}")
        lo, hi = parse_vector(f"{where}.floor[0]", fl[0], 2), parse_vector(f"{where}.floor[1]", fl[1], 2)
        if not (hi[0] > lo[0] and hi[1] > lo[1]):
            raise SceneFormatError(f"{where}.floor: expected lower corner below upper corner, got {fl!r}")
        rooms.append(
            Room(parse_text(f"{where}.id", r["id"]), parse_text(f"{where}.name", r["name"]), (lo, hi),
                 parse_material(f"{where}.floor_material", r.get("floor_material", "parquet")),
                 parse_material(f"{where}.wall_material", r.get("wall_material", "plaster_white")))
        )
    return tuple(rooms)


def parse_walls(d: dict, source: str) -> tuple[Wall, ...]:
    """Validated walls: positive thickness and height, doors within the wall and apart."""
    walls = []
    for where, w in _entries(d, "walls", source, ("id", "start", "end"), _FIELDS[Wall]):
        wall_id = parse_text(f"{where}.id", w["id"])
        start, end = parse_vector(f"{where}.start", w["start"], 2), parse_vector(f"{where}.end", w["end"], 2)
        thickness = parse_number(f"{where}.thickness", w.get("thickness", 0.1), positive=True)
        height = parse_number(f"{where}.height", w.get("height", 2.5), positive=True)
        mats = w.get("materials", ["plaster_white", "plaster_white"])
        if not isinstance(mats, (list, tuple)) or len(mats) != 2:
            raise SceneFormatError(f"{where}.materials: expected [left, right], got {mats!r}")
        doors = tuple(parse_vector(f"{where}.doors[{k}]", dr, 2) for k, dr in enumerate(parse_list(f"{where}.doors", w.get("doors"))))
        materials = tuple(parse_material(f"{where}.materials[{k}]", m) for k, m in enumerate(mats))
        wall = Wall(wall_id, start, end, thickness, height, materials, doors)
        if wall.length <= 0:
            raise SceneFormatError(f"{where}: start and end coincide at {start}")
        at = 0.0
        for off, width in sorted(doors):
            if width <= 0 or off < at or off + width > wall.length + 1e-9:
                raise SceneFormatError(
                    f"{where}: door [{off}, {width}] must have positive width, lie within the wall "
                    f"(length {wall.length:.3f}) and not overlap another door"
                )
            at = off + width
        walls.append(wall)
    return tuple(walls)


def parse_furniture(d: dict, source: str) -> tuple[Furniture, ...]:
    """Validated furniture: known kinds and materials, positive sizes, shelves inside the piece."""
    out = []
    for where, f in _entries(d, "furniture", source, ("id", "name", "category", "position", "size"), _FIELDS[Furniture]):
        fid = parse_text(f"{where}.id", f["id"])
        if not isinstance(f["category"], str) or f["category"] not in FURNITURE:
            raise SceneFormatError(f"{where} ({fid!r}): unknown furniture kind {f['category']!r}; known kinds: {sorted(FURNITURE)}")
        size = parse_vector(f"{where}.size", f["size"], 3)
        if min(size) <= 0:
            raise SceneFormatError(f"{where}.size: expected positive sizes, got {size}")
        shelf_list = parse_list(f"{where}.shelf_heights", f.get("shelf_heights"))
        shelves = tuple(parse_number(f"{where}.shelf_heights[{k}]", s) for k, s in enumerate(shelf_list))
        if any(not 0 < s < size[2] for s in shelves) or list(shelves) != sorted(shelves):
            raise SceneFormatError(f"{where}.shelf_heights: expected ascending heights within (0, {size[2]}), got {list(shelves)}")
        kind = FURNITURE[f["category"]]
        out.append(
            Furniture(
                fid, parse_text(f"{where}.name", f["name"]), f["category"], parse_vector(f"{where}.position", f["position"], 3),
                parse_number(f"{where}.yaw", f.get("yaw", 0.0)), size,
                parse_material(f"{where}.material", f.get("material", kind.default_material)),
                parse_phrases(f"{where}.phrases", f.get("phrases")), shelves,
            )
        )
    return tuple(out)


def support_surface_z(obj, support, *, tol: float = 0.01) -> tuple[float | None, str]:
    """World height of the surface under ``obj`` on ``support`` and its kind.

    ``support`` is ``"floor"``, a :class:`Furniture` or a scene object. Returns
    ``(None, reason)`` when the object's centre is off every surface of the support; otherwise
    the surface whose height is nearest to the object's base, and its kind (``"top"``,
    ``"shelf"``, ``"inside"``, ``"floor"``).
    """
    x, y, z = obj.position
    if support == "floor":
        return 0.0, "floor"
    if isinstance(support, Furniture):
        local = support.to_local((x, y))
        cands = [s for s in support.surfaces() if s.contains(local, tol)]
        if not cands:
            return None, f"its centre ({x:.3f}, {y:.3f}) is off every support surface of {support.id!r}"
        best = min(cands, key=lambda s: abs(support.position[2] + s.z - z))
        return support.position[2] + best.z, best.kind
    # another object: the inner floor of an open container, otherwise its top
    half = np.asarray(support.size[:2]) / 2
    if np.any(np.abs(np.asarray([x, y]) - np.asarray(support.position[:2])) > half + tol):
        return None, f"its centre ({x:.3f}, {y:.3f}) is off {support.id!r}"
    floor = container_floor(support.asset, support.size)
    if floor is not None:
        return support.position[2] + floor, "inside"
    return support.position[2] + support.size[2], "top"


def check_supports(objects, furniture, source: str, *, tol: float = 0.01) -> None:
    """Every object's ``support`` exists and its base rests on a surface of it within ``tol``.

    Raises :class:`~conceptfusion.errors.SceneFormatError` (a ``ValueError``) naming the object
    and the support.
    """
    by_id = {f.id: f for f in furniture}
    objs = {o.id: o for o in objects}
    for o in objects:
        s = getattr(o, "support", None)
        if s is None:
            continue
        if s == o.id:
            raise SceneFormatError(f"{source}: object {o.id!r} ({o.name}) cannot support itself")
        if s != "floor" and s not in by_id and s not in objs:
            raise SceneFormatError(
                f"{source}: object {o.id!r} ({o.name}): support {s!r} is missing; expected 'floor', a furniture id "
                f"({sorted(by_id)}) or an object id"
            )
        target = "floor" if s == "floor" else by_id.get(s) or objs[s]
        z, why = support_surface_z(o, target, tol=tol)
        if z is None:
            raise SceneFormatError(f"{source}: object {o.id!r} ({o.name}) floats: {why}")
        if abs(o.position[2] - z) > tol:
            raise SceneFormatError(
                f"{source}: object {o.id!r} ({o.name}) floats: base at z={o.position[2]:.3f}, but the nearest surface of "
                f"{s!r} is at z={z:.3f} (tolerance {tol} m)"
            )
