"""Camera trajectories over a scene: the standard scan of the map suites, the tower's floor
calibration, the demo and ``cf/SceneScan-v0``.

A trajectory is a list of ``(eye, target)`` pairs in world metres (z up): the camera sits at
``eye`` looking at ``target``. They are plain geometry of the scene description, the same for
every simulator backend; :func:`sim_envs.mujoco.scan.render_views` renders them.
"""

from __future__ import annotations

import math

from sim_envs.scenes.format import Scene

__all__ = ["orbit_trajectory", "room_sweep_trajectory", "scan_trajectory"]


def orbit_trajectory(scene: Scene, num_frames: int, *, radius: float = 1.1, height: float = 0.75) -> list[tuple]:
    """(eye, target) pairs on a circle around the table, looking at its centre."""
    if scene.table is None:
        raise ValueError(f"scene {scene.id}: an orbit needs a table to circle")
    cx, cy, _ = scene.table.center
    target = (cx, cy, scene.table.top_z)
    out = []
    for k in range(num_frames):
        a = 2 * math.pi * k / num_frames - math.pi / 2
        out.append(((cx + radius * math.cos(a), cy + radius * math.sin(a), scene.table.top_z + height), target))
    return out


def room_sweep_trajectory(
    scene: Scene, num_frames: int, *, height: float = 1.3, pitch_deg: float = -22.0, offset: float = 0.0
) -> list[tuple]:
    """(eye, target) pairs turning in place at each room's centre, room after room.

    ``num_frames`` is spread over the rooms (the first rooms get one more when it does not
    divide); in each room the camera, ``height`` metres up, turns through 360 degrees looking
    ``pitch_deg`` below the horizon (negative: down). ``offset`` shifts the start heading.
    """
    if not scene.rooms:
        raise ValueError(f"scene {scene.id}: a room sweep needs rooms; this scene has none")
    n_rooms = len(scene.rooms)
    if num_frames < n_rooms:
        raise ValueError(f"num_frames: expected at least one frame per room ({n_rooms}), got {num_frames}")
    drop = math.tan(math.radians(-pitch_deg))
    out = []
    for k, room in enumerate(scene.rooms):
        n = num_frames // n_rooms + (1 if k < num_frames % n_rooms else 0)
        cx, cy = room.center
        for i in range(n):
            a = offset + 2 * math.pi * i / n
            out.append(((cx, cy, height), (cx + math.cos(a), cy + math.sin(a), height - drop)))
    return out


def scan_trajectory(scene: Scene, num_frames: int) -> list[tuple]:
    """The scan of a scene: a room sweep for household scenes, an orbit around the table otherwise."""
    return room_sweep_trajectory(scene, num_frames) if scene.rooms else orbit_trajectory(scene, num_frames)
