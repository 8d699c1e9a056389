"""Seeded procedural household scenes: connected rooms, furniture along the walls, objects on it.

Layout: 3 rooms (kitchen, living room, study) in a row or an L, or 4 rooms (with a bedroom) in
a 2 x 2 grid; rooms are 3.6-5 m wide. Shared walls get doors 0.95-1.1 m wide so that a
0.25 m-radius base can drive through every room; each room gets 2-5 pieces of furniture with
their backs to the walls (a coffee table in front of the sofa, a chair at the desk), kept out
of a 1.2 m zone in front of every door. At least 20 objects stand on furniture tops, shelf
levels and inside open containers (bowls, baskets, open cabinets), each with a unique name
such as "red mug".
"""

from __future__ import annotations

import math

import numpy as np

from sim_envs.assets.objects import ASSETS, COLORS
from sim_envs.scenes.floorplan import reachable_rooms
from sim_envs.assets.furniture import FURNITURE, Surface
from sim_envs.scenes.household_format import CONTAINER_FLOOR, Furniture, Room, Wall
from sim_envs.scenes.format import Scene, SceneObject

__all__ = ["generate_household", "furnished_apartment", "support_surfaces", "place_on_surface", "door_keep_out", "ROOM_FURNITURE"]

ROOM_FURNITURE: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "kitchen": (("counter", "dining table"), ("counter", "shelf", "cabinet", "basket", "chair")),
    "living room": (("sofa", "coffee table"), ("bookshelf", "cabinet", "basket", "shelf")),
    "study": (("desk", "chair", "bookshelf"), ("shelf", "cabinet", "basket")),
    "bedroom": (("bed",), ("cabinet", "desk", "basket", "bookshelf")),
}
"""Per room type: furniture always placed, and kinds drawn from for the rest (2-5 pieces)."""

_ROOM_MATERIALS = {
    "kitchen": (("tile",), ("plaster_white", "plaster_green")),
    "living room": (("parquet", "carpet"), ("plaster_beige", "plaster_white")),
    "study": (("parquet",), ("plaster_blue", "plaster_white")),
    "bedroom": (("carpet", "parquet"), ("plaster_beige", "plaster_blue")),
}
_KIND_MATERIALS = {
    "counter": ("wood_light", "wood", "wood_dark"), "dining table": ("wood", "wood_light", "wood_dark"),
    "coffee table": ("wood_dark", "wood"), "desk": ("wood_light", "wood", "wood_dark"), "shelf": ("metal", "wood_light"),
    "bookshelf": ("wood", "wood_dark", "wood_light"), "cabinet": ("wood_dark", "wood", "wood_light"),
    "sofa": ("fabric_grey", "fabric_blue", "fabric_green", "fabric_red"), "bed": ("fabric_blue", "fabric_grey", "fabric_red", "linen"),
    "chair": ("wood", "wood_dark", "metal_dark"), "basket": ("wicker",),
}
_ADJECTIVE = {
    "wood": "wooden", "wood_dark": "dark wooden", "wood_light": "light wooden", "metal": "metal", "metal_dark": "black metal",
    "fabric_grey": "grey", "fabric_blue": "blue", "fabric_green": "green", "fabric_red": "red", "linen": "white", "wicker": "wicker",
}
_OBJECT_KINDS = tuple(k for k in ("ball", "book", "bottle", "bowl", "box", "can", "mug") if k in ASSETS)
_WALL_T, _WALL_H, _DOOR_CLEAR = 0.1, 2.5, 1.2
_YAW_FOR_SIDE = {"S": math.pi, "N": 0.0, "E": -math.pi / 2, "W": math.pi / 2}  # back of the piece to that wall


def _layout(rng: np.random.Generator):
    """Cells (col, row), column widths and row depths, adjacency pairs with doors."""
    four = rng.random() < 0.4
    if four:
        cells = [(0, 0), (1, 0), (0, 1), (1, 1)]
    elif rng.random() < 0.5:
        cells = [(0, 0), (1, 0), (2, 0)]
    else:
        cells = [(0, 0), (1, 0), (int(rng.integers(2)), 1)]
    ncol, nrow = max(c for c, _ in cells) + 1, max(r for _, r in cells) + 1
    widths = rng.uniform(3.6, 5.0, ncol)
    depths = rng.uniform(3.6, 4.8, nrow)
    adj = [(i, j) for i in range(len(cells)) for j in range(i + 1, len(cells)) if abs(cells[i][0] - cells[j][0]) + abs(cells[i][1] - cells[j][1]) == 1]
    order = rng.permutation(len(adj))
    doors, comp = [], list(range(len(cells)))  # a random spanning tree, then maybe one more door

    def find(a):
        while comp[a] != a:
            a = comp[a]
        return a

    extra = []
    for k in order:
        i, j = adj[k]
        if find(i) != find(j):
            comp[find(i)] = find(j)
            doors.append(adj[k])
        else:
            extra.append(adj[k])
    if extra and rng.random() < 0.5:
        doors.append(extra[0])
    return cells, widths, depths, sorted(doors)


def _rooms_and_walls(rng, cells, widths, depths, doors):
    names = ["kitchen", "living room", "study"] + (["bedroom"] if len(cells) == 4 else [])
    names = [names[int(k)] for k in rng.permutation(len(names))]
    x_off = np.concatenate([[0], np.cumsum(widths)]) - widths.sum() / 2
    y_off = np.concatenate([[0], np.cumsum(depths)]) - depths.sum() / 2
    rooms = []
    for k, ((c, r), name) in enumerate(zip(cells, names)):
        floors, walls = _ROOM_MATERIALS[name]
        rooms.append(
            Room(f"room{k}", name, ((float(x_off[c]), float(y_off[r])), (float(x_off[c + 1]), float(y_off[r + 1]))),
                 floors[int(rng.integers(len(floors)))], walls[int(rng.integers(len(walls)))])
        )
    index = {cell: k for k, cell in enumerate(cells)}
    walls, door_spans = [], {}  # door_spans[room id] -> list of (centre xy, along-wall unit, width)
    for k, (c, r) in enumerate(cells):
        (x0, y0), (x1, y1) = rooms[k].floor
        # side, neighbour cell, edge start/end (walking with the room on the left)
        for side, nb, a, b in (("S", (c, r - 1), (x0, y0), (x1, y0)), ("E", (c + 1, r), (x1, y0), (x1, y1)),
                               ("N", (c, r + 1), (x1, y1), (x0, y1)), ("W", (c - 1, r), (x0, y1), (x0, y0))):
            j = index.get(nb)
            if j is not None and j < k:
                continue  # built from the other room
            length = math.dist(a, b)
            u = ((b[0] - a[0]) / length, (b[1] - a[1]) / length)
            start = (a[0] - u[0] * _WALL_T / 2, a[1] - u[1] * _WALL_T / 2)
            end = (b[0] + u[0] * _WALL_T / 2, b[1] + u[1] * _WALL_T / 2)
            wall_doors = ()
            if j is not None and tuple(sorted((k, j))) in doors:
                width = float(rng.uniform(0.95, 1.1))
                off = float(rng.uniform(0.4, length - 0.4 - width))
                wall_doors = ((round(off + _WALL_T / 2, 4), round(width, 4)),)
                centre = (a[0] + u[0] * (off + width / 2), a[1] + u[1] * (off + width / 2))
                for rid in (k, j):
                    door_spans.setdefault(rooms[rid].id, []).append((centre, u, width))
            right = rooms[j].wall_material if j is not None else "plaster_white"
            walls.append(Wall(f"wall{len(walls)}", start, end, _WALL_T, _WALL_H, (rooms[k].wall_material, right), wall_doors))
    return rooms, walls, door_spans


def _overlaps(lo, hi, boxes, gap: float) -> bool:
    return any(np.all(np.minimum(hi, h2) - np.maximum(lo, l2) > -gap) for l2, h2 in boxes)


def _piece(rng, fid: str, kind: str, xy, yaw: float, names: set[str]) -> Furniture:
    spec = FURNITURE[kind]
    scale = rng.uniform(0.92, 1.08, 3)
    size = tuple(round(float(s * k), 3) for s, k in zip(spec.default_size, scale))
    mats = _KIND_MATERIALS[kind]
    mat = mats[int(rng.integers(len(mats)))]
    name = f"{_ADJECTIVE[mat]} {kind}"
    n = 2
    while name in names:
        name, n = f"{_ADJECTIVE[mat]} {kind} {n}", n + 1
    return Furniture(fid, name, kind, (round(float(xy[0]), 4), round(float(xy[1]), 4), 0.0), yaw, size, mat, spec.phrases, spec.default_shelves(size[2]))


def _front(f: Furniture, dist: float) -> np.ndarray:
    """World xy ``dist`` metres in front of the piece's centre (its front faces local -y)."""
    return f.to_world((0.0, -dist))


def door_keep_out(doors) -> list[tuple[np.ndarray, np.ndarray]]:
    """World xy boxes (lower, upper corner) kept free in front of and behind each door.

    ``doors`` are ``(centre xy, along-wall unit vector, width)`` as the layout records them.
    """
    keep_out = []
    for (cx, cy), u, width in doors:
        along, across = (width / 2 + 0.3), _DOOR_CLEAR
        hx, hy = (along, across) if abs(u[0]) > 0.5 else (across, along)
        keep_out.append((np.array([cx - hx, cy - hy]), np.array([cx + hx, cy + hy])))
    return keep_out


def _furnish(rng, room: Room, doors, names: set[str], start_index: int) -> list[Furniture]:
    required, optional = ROOM_FURNITURE[room.name]
    n = int(rng.integers(max(2, len(required)), 6))
    extra = [optional[int(k)] for k in rng.permutation(len(optional))]
    kinds = list(required) + extra[: n - len(required)]
    (x0, y0), (x1, y1) = room.floor
    ix0, iy0, ix1, iy1 = x0 + _WALL_T / 2 + 0.02, y0 + _WALL_T / 2 + 0.02, x1 - _WALL_T / 2 - 0.02, y1 - _WALL_T / 2 - 0.02
    keep_out = door_keep_out(doors)
    placed: list[Furniture] = []
    for kind in kinds:
        fid = f"f{start_index + len(placed)}"
        anchor = {"coffee table": "sofa", "chair": "desk"}.get(kind)
        anchors = [p for p in placed if p.category == anchor]
        for attempt in range(60):
            if anchors and attempt < 5:  # in front of its partner, facing it (chair) or parallel (coffee table)
                a = anchors[0]
                size = FURNITURE[kind].default_size
                if kind == "chair":
                    f = _piece(rng, fid, kind, _front(a, a.size[1] / 2 + 0.05 + size[1] / 2), math.remainder(a.yaw + math.pi, 2 * math.pi), names)
                else:
                    f = _piece(rng, fid, kind, _front(a, a.size[1] / 2 + 0.45 + size[1] / 2), a.yaw, names)
            else:
                side = "SENW"[int(rng.integers(4))]
                yaw = _YAW_FOR_SIDE[side]
                f = _piece(rng, fid, kind, (0.0, 0.0), yaw, names)
                w, d = f.size[0], f.size[1]
                if side in "NS":
                    x = rng.uniform(ix0 + w / 2, ix1 - w / 2) if ix1 - ix0 > w else None
                    y = iy1 - d / 2 if side == "N" else iy0 + d / 2
                else:
                    y = rng.uniform(iy0 + w / 2, iy1 - w / 2) if iy1 - iy0 > w else None
                    x = ix1 - d / 2 if side == "E" else ix0 + d / 2
                if x is None or y is None:
                    continue
                f = Furniture(f.id, f.name, f.category, (round(float(x), 4), round(float(y), 4), 0.0), yaw, f.size, f.material, f.phrases, f.shelf_heights)
            lo, hi = f.footprint()
            if lo[0] < ix0 - 1e-3 or lo[1] < iy0 - 1e-3 or hi[0] > ix1 + 1e-3 or hi[1] > iy1 + 1e-3:
                continue
            gap = 0.0 if anchors and attempt < 5 else 0.12
            if _overlaps(lo, hi, [p.footprint() for p in placed], gap) or _overlaps(lo, hi, keep_out, 0.0):
                continue
            placed.append(f)
            names.add(f.name)
            break
    return placed


def support_surfaces(furniture: list[Furniture], max_z: float = 1.25) -> list[tuple[Furniture, Surface, float]]:
    """(piece, surface, free height above it) for every surface low enough for a 1.3 m camera to see."""
    out = []
    for f in furniture:
        ss = sorted(f.surfaces(), key=lambda s: s.z)
        for k, s in enumerate(ss):
            if s.z > max_z:
                continue
            clear = ss[k + 1].z - 0.02 - s.z if s.kind in ("shelf", "inside") and k + 1 < len(ss) else 0.5
            out.append((f, s, clear))
    return out


def _new_object(rng, oid: str, kind: str, color: str, scale=(0.9, 1.15)) -> SceneObject:
    a = ASSETS[kind]
    size = tuple(round(float(s) * float(rng.uniform(*scale)), 4) for s in a.default_size)
    return SceneObject(oid, f"{color} {a.category}", a.category, kind, color, (0.0, 0.0, 0.0), 0.0, size, (f"a {color} {a.category}",) + a.phrases)


def place_on_surface(rng, obj: SceneObject, f: Furniture, s: Surface, clear: float, taken: list) -> SceneObject | None:
    """``obj`` moved to a random free spot of surface ``s`` of piece ``f`` at a random yaw, or None.

    None when it is taller than ``clear`` - 3 cm, does not fit, or its footprint (in the piece's
    frame) comes within 3 cm of a box in ``taken``; on success its box is appended to ``taken``.
    On shelves and inside cabinets it stays in the front 60 % (visible from the room).
    """
    if obj.size[2] > clear - 0.03:
        return None
    rel = float(rng.uniform(-math.pi, math.pi))
    c, sn = abs(math.cos(rel)), abs(math.sin(rel))
    hx, hy = (c * obj.size[0] + sn * obj.size[1]) / 2, (sn * obj.size[0] + c * obj.size[1]) / 2
    lo_y = s.lo[1] + hy
    hi_y = s.hi[1] - hy if s.kind == "top" else min(s.hi[1] - hy, s.lo[1] + 0.6 * (s.hi[1] - s.lo[1]))
    if s.hi[0] - hx <= s.lo[0] + hx or hi_y <= lo_y:
        return None
    local = np.array([rng.uniform(s.lo[0] + hx, s.hi[0] - hx), rng.uniform(lo_y, hi_y)])
    box = (local - [hx, hy], local + [hx, hy])
    if _overlaps(*box, taken, 0.03):
        return None
    taken.append(box)
    xy = f.to_world(local)
    yaw = math.remainder(f.yaw + rel, 2 * math.pi)
    return SceneObject(obj.id, obj.name, obj.category, obj.asset, obj.color, (round(float(xy[0]), 4), round(float(xy[1]), 4), round(f.position[2] + s.z, 4)),
                       round(yaw, 4), obj.size, obj.phrases, f.id)


def _unique_kind_color(rng, names: set[str], kinds=_OBJECT_KINDS) -> tuple[str, str]:
    colors = sorted(COLORS)
    while True:
        kind, color = kinds[int(rng.integers(len(kinds)))], colors[int(rng.integers(len(colors)))]
        if f"{color} {ASSETS[kind].category}" not in names:
            return kind, color


def _populate(rng, furniture: list[Furniture], min_objects: int) -> list[SceneObject]:
    surfaces = support_surfaces(furniture)
    taken = {i: [] for i in range(len(surfaces))}
    objects: list[SceneObject] = []
    names: set[str] = set()
    target = int(rng.integers(min_objects + 2, min_objects + 9))

    def put(kind: str, color: str, where: list[int]) -> SceneObject | None:
        proto = _new_object(rng, f"obj{len(objects)}", kind, color)
        for _ in range(12):
            i = where[int(rng.integers(len(where)))]
            f, s, clear = surfaces[i]
            o = place_on_surface(rng, proto, f, s, clear - (0.14 if kind == "bowl" else 0.0), taken[i])
            if o is not None:
                objects.append(o)
                names.add(o.name)
                return o
        return None

    tops = [i for i, (_, s, _) in enumerate(surfaces) if s.kind == "top"] or list(range(len(surfaces)))
    bowls = [put("bowl", _unique_kind_color(rng, names, ("bowl",))[1], tops) for _ in range(2)]
    for bowl in (b for b in bowls if b is not None):  # something small in each bowl
        kind, color = _unique_kind_color(rng, names, tuple(k for k in ("ball", "can") if k in ASSETS))
        proto = _new_object(rng, f"obj{len(objects)}", kind, color, scale=(0.8, 0.9))
        x, y, z = bowl.position
        objects.append(SceneObject(proto.id, proto.name, proto.category, kind, color, (x, y, round(z + CONTAINER_FLOOR["bowl"], 4)),
                                   round(float(rng.uniform(-math.pi, math.pi)), 4), proto.size, proto.phrases, bowl.id))
        names.add(proto.name)
    everywhere = list(range(len(surfaces)))
    for _ in range(400):
        if len(objects) >= target:
            break
        kind, color = _unique_kind_color(rng, names, tuple(k for k in _OBJECT_KINDS if k != "bowl"))
        put(kind, color, everywhere)
    return objects


def generate_household(seed: int, *, min_objects: int = 20) -> Scene:
    """A household scene of 3-4 connected rooms, furniture and at least ``min_objects`` objects.

    Randomness: everything follows from ``seed`` (``np.random.default_rng(seed)``). The
    furniture is re-drawn (same stream) until a 0.25 m-radius disc can reach every room.
    """
    rng = np.random.default_rng(seed)
    scene, _ = furnished_apartment(rng, seed, f"household-{seed:04d}")
    furniture = list(scene.furniture)
    objects = _populate(rng, furniture, min_objects)
    if len(objects) < min_objects:
        raise RuntimeError(f"generate_household({seed}): placed {len(objects)} objects, expected at least {min_objects}")
    return Scene(scene.id, "household", int(seed), None, tuple(objects), None, {}, scene.rooms, scene.walls, tuple(furniture))


def furnished_apartment(rng: np.random.Generator, seed: int, scene_id: str) -> tuple[Scene, dict]:
    """Rooms, walls with doors and furniture (no objects) drawn from ``rng``, and the doors.

    The furniture is re-drawn (same stream) until a 0.25 m-radius disc can reach every room.
    Returns the scene and, per room id, its doors as ``(centre xy, along-wall unit, width)``.
    """
    cells, widths, depths, doors = _layout(rng)
    rooms, walls, door_spans = _rooms_and_walls(rng, cells, widths, depths, doors)
    for _ in range(20):
        furniture, fnames = [], set()
        for room in rooms:
            furniture += _furnish(rng, room, door_spans.get(room.id, []), fnames, len(furniture))
        scene = Scene(scene_id, "household", int(seed), None, (), None, {}, tuple(rooms), tuple(walls), tuple(furniture))
        if reachable_rooms(scene) == {r.id for r in rooms}:
            return scene, door_spans
    raise RuntimeError(f"generate_household({seed}): no furniture arrangement left every room reachable")
