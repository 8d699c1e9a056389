"""2-D occupancy of a household scene's floor: walls, doors and furniture, for reachability checks.

The grid is axis-aligned over the rooms' bounding box; row ``i``, column ``j`` is the cell
whose centre is ``origin + ((j + 0.5) * cell, (i + 0.5) * cell)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from conceptfusion.tasks import MAX_ROOMS, ROOM_TYPES

__all__ = ["Occupancy", "occupancy_grid", "reachable_rooms", "room_plan_spaces", "room_plan_observation"]


@dataclass(frozen=True)
class Occupancy:
    """Blocked floor cells.

    Shape:
        ``blocked_hw`` (H, W) bool; ``origin`` (2,) world xy of the grid's lower-left corner.
    """

    blocked_hw: np.ndarray
    origin: np.ndarray
    cell: float

    def clearance(self) -> np.ndarray:
        """(H, W) float: metres from each cell to the nearest blocked cell (0 on blocked cells);
        a disc of radius r centred on a cell is clear where this exceeds r."""
        from scipy import ndimage

        return ndimage.distance_transform_edt(~self.blocked_hw) * self.cell

    def centres(self) -> tuple[np.ndarray, np.ndarray]:
        """World x (H, W) and y (H, W) of every cell centre."""
        h, w = self.blocked_hw.shape
        xs = self.origin[0] + (np.arange(w) + 0.5) * self.cell
        ys = self.origin[1] + (np.arange(h) + 0.5) * self.cell
        return np.meshgrid(xs, ys)


def _in_box(x, y, centre, yaw: float, half) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    dx, dy = x - centre[0], y - centre[1]
    return (np.abs(c * dx + s * dy) <= half[0]) & (np.abs(-s * dx + c * dy) <= half[1])


def occupancy_grid(scene, *, cell: float = 0.05, margin: float = 0.5) -> Occupancy:
    """Cells outside every room, on a wall (doors are gaps), under furniture or under an object
    standing on the floor (``support == "floor"``) are blocked.

    ``scene`` must have rooms (a household scene); ``ValueError`` otherwise.
    """
    if not scene.rooms:
        raise ValueError(f"scene {scene.id}: an occupancy grid needs rooms; this scene has none")
    if cell <= 0:
        raise ValueError(f"cell: expected a positive size, got {cell}")
    lo = np.min([r.floor[0] for r in scene.rooms], axis=0) - margin
    hi = np.max([r.floor[1] for r in scene.rooms], axis=0) + margin
    w, h = (int(math.ceil(v)) for v in (hi - lo) / cell)
    grid = Occupancy(np.zeros((h, w), bool), lo.astype(np.float64), float(cell))
    x, y = grid.centres()
    inside = np.zeros((h, w), bool)
    for r in scene.rooms:
        (x0, y0), (x1, y1) = r.floor
        inside |= (x >= x0) & (x <= x1) & (y >= y0) & (y <= y1)
    blocked = ~inside
    for wall in scene.walls:
        (sx, sy), (ex, ey) = wall.start, wall.end
        yaw = math.atan2(ey - sy, ex - sx)
        ux, uy = (ex - sx) / wall.length, (ey - sy) / wall.length
        for a, b in wall.solid_spans():
            m = (a + b) / 2
            blocked |= _in_box(x, y, (sx + ux * m, sy + uy * m), yaw, ((b - a) / 2, wall.thickness / 2))
    for f in scene.furniture:
        blocked |= _in_box(x, y, f.position, f.yaw, (f.size[0] / 2, f.size[1] / 2))
    for o in scene.objects:  # objects standing on the floor (a chair, a bench) block it like furniture
        if getattr(o, "support", None) == "floor":
            blocked |= _in_box(x, y, o.position, o.yaw, (o.size[0] / 2, o.size[1] / 2))
    return Occupancy(blocked, grid.origin, grid.cell)


def reachable_rooms(scene, *, radius: float = 0.25, cell: float = 0.05, start_room: str | None = None) -> set[str]:
    """Ids of the rooms a disc of ``radius`` can drive into from ``start_room`` (default: the first).

    The disc's centre may visit a cell when every blocked cell is more than ``radius`` away;
    the start is the largest such free region within the start room.
    """
    from scipy import ndimage

    occ = occupancy_grid(scene, cell=cell)
    free = occ.clearance() > radius
    labels, n = ndimage.label(free)
    if n == 0:
        return set()
    x, y = occ.centres()
    rooms = {r.id: (x >= r.floor[0][0]) & (x <= r.floor[1][0]) & (y >= r.floor[0][1]) & (y <= r.floor[1][1]) for r in scene.rooms}
    start = start_room or scene.rooms[0].id
    if start not in rooms:
        raise ValueError(f"start_room: expected one of {sorted(rooms)}, got {start!r}")
    counts = np.bincount(labels[rooms[start] & free], minlength=n + 1)
    counts[0] = 0
    if counts.max() == 0:
        return set()
    comp = labels == int(np.argmax(counts))
    return {rid for rid, mask in rooms.items() if (mask & comp).any()}


def room_plan_spaces() -> dict:
    """The observation spaces of a labelled floor plan: ``room_boxes`` (:data:`~conceptfusion.tasks.MAX_ROOMS`, 4) and
    ``room_types`` (:data:`~conceptfusion.tasks.MAX_ROOMS`,) (see :func:`room_plan_observation`)."""
    from gymnasium import spaces

    return {
        "room_boxes": spaces.Box(-np.inf, np.inf, (MAX_ROOMS, 4), np.float32),
        "room_types": spaces.MultiDiscrete(np.full(MAX_ROOMS, len(ROOM_TYPES) + 1, np.int64)),
    }


def room_plan_observation(scene, where: str) -> dict[str, np.ndarray]:
    """A scene's labelled floor plan: the outline of every room and its name, nothing else.

    Shape: returns ``room_boxes`` (MAX_ROOMS, 4) float32, row ``i`` ``[x_min, y_min, x_max, y_max]``
    of room ``i`` (zeros past the last room), and ``room_types`` (MAX_ROOMS,) int64, ``k + 1`` for
    ``ROOM_TYPES[k]`` (0 past the last room).

    Raises:
        SimError: more than :data:`~conceptfusion.tasks.MAX_ROOMS` rooms, or a room name not in :data:`~conceptfusion.tasks.ROOM_TYPES`.
    """
    from conceptfusion.errors import SimError

    if len(scene.rooms) > MAX_ROOMS:
        raise SimError(f"{where}: a room plan holds at most {MAX_ROOMS} rooms; scene {scene.id} has {len(scene.rooms)}")
    boxes = np.zeros((MAX_ROOMS, 4), np.float32)
    types = np.zeros(MAX_ROOMS, np.int64)
    for i, room in enumerate(scene.rooms):
        if room.name not in ROOM_TYPES:
            raise SimError(f"{where}: scene {scene.id}: rooms[{i}].name {room.name!r}: a room plan names rooms by one of "
                           f"{', '.join(ROOM_TYPES)}")
        (x0, y0), (x1, y1) = room.floor
        boxes[i] = (min(x0, x1), min(y0, y1), max(x0, x1), max(y0, y1))
        types[i] = ROOM_TYPES.index(room.name) + 1
    return {"room_boxes": boxes, "room_types": types}

