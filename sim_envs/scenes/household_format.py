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
from dataclasses import dataclass

import numpy as np

from sim_envs.assets.furniture import FURNITURE, MATERIALS, Surface

__all__ = [
    "parse_vector",
    "Room", "Wall", "Furniture", "CONTAINER_FLOOR", "parse_rooms", "parse_walls", "parse_furniture",
    "check_supports", "support_surface_z",
]

CONTAINER_FLOOR: dict[str, float] = {"bowl": 0.01}
"""Object assets that are open containers: height of the inner floor above the base (metres)."""


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


def parse_vector(name: str, value, n: int) -> tuple[float, ...]:
    """``value`` as ``n`` finite floats; ``ValueError`` naming the field ``name`` otherwise."""
    try:
        v = tuple(float(x) for x in value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected {n} numbers, got {value!r}") from None
    if len(v) != n or not all(np.isfinite(v)):
        raise ValueError(f"{name}: expected {n} finite numbers, got {value!r}")
    return v


def _material(where: str, name) -> str:
    if name not in MATERIALS:
        raise ValueError(f"{where}: unknown material {name!r}; known materials: {list(MATERIALS)}")
    return str(name)


def _entries(d: dict, key: str, source: str, required: tuple[str, ...]):
    for i, e in enumerate(d.get(key) or []):
        where = f"{source}: {key}[{i}]"
        if not isinstance(e, dict):
            raise ValueError(f"{where}: expected an object, got {type(e).__name__}")
        for k in required:
            if k not in e:
                raise ValueError(f"{where}: missing field {k!r}")
        yield where, e


def parse_rooms(d: dict, source: str) -> tuple[Room, ...]:
    """Validated rooms of a scene document (empty when it has none)."""
    rooms = []
    for where, r in _entries(d, "rooms", source, ("id", "name", "floor")):
        fl = r["floor"]
        if not isinstance(fl, (list, tuple)) or len(fl) != 2:
            raise ValueError(f"{where}.floor: expected [[x0, y0], [x1, y1]], got {fl!r}")
        lo, hi = parse_vector(f"{where}.floor[0]", fl[0], 2), parse_vector(f"{where}.floor[1]", fl[1], 2)
        if not (hi[0] > lo[0] and hi[1] > lo[1]):
            raise ValueError(f"{where}.floor: expected lower corner below upper corner, got {fl!r}")
        rooms.append(
            Room(str(r["id"]), str(r["name"]), (lo, hi), _material(f"{where}.floor_material", r.get("floor_material", "parquet")),
                 _material(f"{where}.wall_material", r.get("wall_material", "plaster_white")))
        )
    return tuple(rooms)


def parse_walls(d: dict, source: str) -> tuple[Wall, ...]:
    """Validated walls: positive thickness and height, doors within the wall and apart."""
    walls = []
    for where, w in _entries(d, "walls", source, ("id", "start", "end")):
        start, end = parse_vector(f"{where}.start", w["start"], 2), parse_vector(f"{where}.end", w["end"], 2)
        thickness, height = float(w.get("thickness", 0.1)), float(w.get("height", 2.5))
        if thickness <= 0 or height <= 0:
            raise ValueError(f"{where}: expected positive thickness and height, got {thickness}, {height}")
        mats = w.get("materials", ["plaster_white", "plaster_white"])
        if not isinstance(mats, (list, tuple)) or len(mats) != 2:
            raise ValueError(f"{where}.materials: expected [left, right], got {mats!r}")
        doors = tuple(parse_vector(f"{where}.doors[{k}]", dr, 2) for k, dr in enumerate(w.get("doors") or []))
        wall = Wall(str(w["id"]), start, end, thickness, height, tuple(_material(f"{where}.materials", m) for m in mats), doors)
        if wall.length <= 0:
            raise ValueError(f"{where}: start and end coincide at {start}")
        at = 0.0
        for off, width in sorted(doors):
            if width <= 0 or off < at or off + width > wall.length + 1e-9:
                raise ValueError(f"{where}: door [{off}, {width}] must have positive width, lie within the wall (length {wall.length:.3f}) and not overlap another door")
            at = off + width
        walls.append(wall)
    return tuple(walls)


def parse_furniture(d: dict, source: str) -> tuple[Furniture, ...]:
    """Validated furniture: known kinds and materials, positive sizes, shelves inside the piece."""
    out = []
    for where, f in _entries(d, "furniture", source, ("id", "name", "category", "position", "size")):
        if f["category"] not in FURNITURE:
            raise ValueError(f"{where} ({f['id']!r}): unknown furniture kind {f['category']!r}; known kinds: {sorted(FURNITURE)}")
        size = parse_vector(f"{where}.size", f["size"], 3)
        if min(size) <= 0:
            raise ValueError(f"{where}.size: expected positive sizes, got {size}")
        shelves = tuple(float(s) for s in f.get("shelf_heights") or ())
        if any(not 0 < s < size[2] for s in shelves) or list(shelves) != sorted(shelves):
            raise ValueError(f"{where}.shelf_heights: expected ascending heights within (0, {size[2]}), got {list(shelves)}")
        kind = FURNITURE[f["category"]]
        out.append(
            Furniture(
                str(f["id"]), str(f["name"]), str(f["category"]), parse_vector(f"{where}.position", f["position"], 3),
                float(f.get("yaw", 0.0)), size, _material(f"{where}.material", f.get("material", kind.default_material)),
                tuple(str(p) for p in f.get("phrases", ())), shelves,
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
    if support.asset in CONTAINER_FLOOR:
        return support.position[2] + CONTAINER_FLOOR[support.asset], "inside"
    return support.position[2] + support.size[2], "top"


def check_supports(objects, furniture, source: str, *, tol: float = 0.01) -> None:
    """Every object's ``support`` exists and its base rests on a surface of it within ``tol``.

    Raises ``ValueError`` naming the object and the support.
    """
    by_id = {f.id: f for f in furniture}
    objs = {o.id: o for o in objects}
    for o in objects:
        s = getattr(o, "support", None)
        if s is None:
            continue
        if s == o.id:
            raise ValueError(f"{source}: object {o.id!r} ({o.name}) cannot support itself")
        if s != "floor" and s not in by_id and s not in objs:
            raise ValueError(
                f"{source}: object {o.id!r} ({o.name}): support {s!r} is missing; expected 'floor', a furniture id "
                f"({sorted(by_id)}) or an object id"
            )
        target = "floor" if s == "floor" else by_id.get(s) or objs[s]
        z, why = support_surface_z(o, target, tol=tol)
        if z is None:
            raise ValueError(f"{source}: object {o.id!r} ({o.name}) floats: {why}")
        if abs(o.position[2] - z) > tol:
            raise ValueError(
                f"{source}: object {o.id!r} ({o.name}) floats: base at z={o.position[2]:.3f}, but the nearest surface of "
                f"{s!r} is at z={z:.3f} (tolerance {tol} m)"
            )
