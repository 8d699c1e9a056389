"""Views of v2 apartments from a robot base's height, for the v2 tower's training data.

The table arrangements of :mod:`tower_training.library_views` show objects from 0.5-1.4 m on a
wooden table. An object-search agent sees them otherwise: from a camera about 1.2 m above the
floor, one to a few metres away, on shelves, sofas and cabinets, against walls and furniture.
:func:`random_room_views` renders such views of household v2 apartments
(:func:`~sim_envs.scenes.gen_household_v2.generate_household_v2`): each view picks one of the
apartment's objects, a free floor cell at a random distance from it (the robot's footprint
clear of walls and furniture), an eye height around the search camera's, and looks at the
object with some jitter, so the object may sit anywhere in the frame, partly cut or hidden.

Which instances an apartment holds follows from its seed's role in the split file
(``tower_train`` seeds: TRAIN instances only), so these views never show a validation or test
instance. Each view is a :class:`~tower_training.library_views.LibraryView`, labelled with
instance ids like the table views.

Randomness: a ``np.random.Generator`` passed in; the apartments follow from their seeds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterator, Sequence

import numpy as np

from tower_training.library_views import LibraryView, labelled_views
from tower_training.views import check_view_config

__all__ = ["RoomViewConfig", "room_poses", "random_room_views"]


@dataclass(frozen=True)
class RoomViewConfig:
    """Where the cameras stand in an apartment and how they render."""

    width: int = 320
    """Image width in pixels."""
    height: int = 240
    """Image height in pixels."""
    fovy_deg: float = 70.0
    """Vertical field of view (the search environment's)."""
    distance_m: tuple[float, float] = (0.7, 3.5)
    """Horizontal distance from the camera to the object it looks at (range)."""
    eye_height_m: tuple[float, float] = (0.9, 1.45)
    """Camera height above the floor (range; the search camera stands at 1.2 m)."""
    target_jitter_m: float = 0.3
    """The look-at point is the object's centre plus a uniform offset of at most this per axis."""
    robot_radius_m: float = 0.25
    """Cameras stand only where a disc of this radius is clear of walls and furniture."""
    light_gain: tuple[float, float] = (0.6, 1.25)
    """Common factor on the lights' diffuse colour, per view (range)."""

    def __post_init__(self) -> None:
        check_view_config(self, ("distance_m", "eye_height_m", "light_gain"))
        if not 0 < self.fovy_deg < 180:
            raise ValueError(f"fovy_deg: expected a value in (0, 180), got {self.fovy_deg}")
        if self.target_jitter_m < 0 or self.robot_radius_m < 0:
            raise ValueError("target_jitter_m, robot_radius_m: expected values >= 0")


def _free_cells(scene, radius: float) -> np.ndarray:
    """World xy (n, 2) of the floor cells where the robot's disc is clear."""
    from sim_envs.scenes.floorplan import occupancy_grid

    occ = occupancy_grid(scene, cell=0.05)
    x, y = occ.centres()
    free = occ.clearance() > radius
    return np.stack([x[free], y[free]], axis=1)


def _same_room(scene, cells_n2: np.ndarray, xy) -> np.ndarray:
    """(n,) bool: the cells on the floor of the room that holds ``xy`` (all False outside rooms)."""
    for r in scene.rooms:
        (x0, y0), (x1, y1) = r.floor
        if x0 <= xy[0] <= x1 and y0 <= xy[1] <= y1:
            return (cells_n2[:, 0] >= x0) & (cells_n2[:, 0] <= x1) & (cells_n2[:, 1] >= y0) & (cells_n2[:, 1] <= y1)
    return np.zeros(len(cells_n2), bool)


def room_poses(scene, ms, views: int, rng: np.random.Generator, config: RoomViewConfig) -> Iterator[tuple]:
    """``views`` random (eye, target) pairs in an apartment; before yielding each, set the
    lights' random brightness for that view.

    A view's object is drawn uniformly from ``scene.objects``; the camera stands on a free cell
    of the object's room (so walls rarely hide it) within ``distance_m`` of it; when there is
    none, another object is drawn (at most 20 times, then the nearest free cell anywhere).
    """
    if not scene.objects:
        raise ValueError(f"scene {scene.id}: expected objects to look at, got none")
    cells = _free_cells(scene, config.robot_radius_m)
    if not len(cells):
        raise ValueError(f"scene {scene.id}: no floor cell is clear for a robot of radius {config.robot_radius_m} m")
    base_light = ms.model.light_diffuse.copy()
    lo, hi = config.distance_m
    for _ in range(views):
        for _try in range(20):
            obj = scene.objects[int(rng.integers(len(scene.objects)))]
            centre = np.array(obj.position, float) + np.array([0.0, 0.0, obj.size[2] / 2])
            d = np.linalg.norm(cells - centre[:2], axis=1)
            ok = np.flatnonzero((d >= lo) & (d <= hi) & _same_room(scene, cells, centre[:2]))
            if len(ok):
                xy = cells[ok[int(rng.integers(len(ok)))]]
                break
        else:
            xy = cells[int(np.argmin(d))]
        eye = (float(xy[0]), float(xy[1]), float(rng.uniform(*config.eye_height_m)))
        j = config.target_jitter_m
        target = tuple(float(v) for v in centre + rng.uniform(-j, j, 3))
        if math.hypot(target[0] - eye[0], target[1] - eye[1]) < 1e-3:  # never look straight down
            target = (target[0] + 0.1, target[1], target[2])
        ms.model.light_diffuse[:] = base_light * rng.uniform(*config.light_gain)
        yield eye, target


def random_room_views(seeds: Sequence[int], views_per_scene: int, rng: np.random.Generator,
                      config: RoomViewConfig = RoomViewConfig()) -> Iterator[LibraryView]:
    """Render ``views_per_scene`` random views of ``generate_household_v2(seed)`` for each seed
    (:func:`room_poses`); each view's randomness is drawn from ``rng`` when the view is asked for."""
    from sim_envs.scenes.gen_household_v2 import generate_household_v2

    return labelled_views(seeds, generate_household_v2, room_poses, views_per_scene, rng, config)
