"""Synthetic scenes for the planner tests: a room point cloud (world frame, z up)."""

from __future__ import annotations

import numpy as np
import pytest


def room_points(*, box: bool = True, spacing: float = 0.025) -> np.ndarray:
    """A 4 m x 3 m room (x in [0, 4], y in [0, 3]) as a world point cloud, z up.

    Floor points at z = 0 everywhere, walls along the four sides from z = 0 to 2 m, a
    0.6 m x 0.6 m x 0.5 m box centred at (2.0, 1.5), a ceiling lamp at z = 2.2 above (3.0, 2.0)
    and low clutter (z = 0.04) around (1.0, 2.5).
    """
    xs = np.arange(0.0, 4.0 + 1e-9, spacing)
    ys = np.arange(0.0, 3.0 + 1e-9, spacing)
    zs = np.arange(0.0, 2.0 + 1e-9, 0.1)
    fx, fy = np.meshgrid(xs, ys)
    floor = np.stack([fx.ravel(), fy.ravel(), np.zeros(fx.size)], axis=1)
    walls = []
    for z in zs:
        walls.append(np.stack([xs, np.zeros_like(xs), np.full_like(xs, z)], axis=1))
        walls.append(np.stack([xs, np.full_like(xs, 3.0), np.full_like(xs, z)], axis=1))
        walls.append(np.stack([np.zeros_like(ys), ys, np.full_like(ys, z)], axis=1))
        walls.append(np.stack([np.full_like(ys, 4.0), ys, np.full_like(ys, z)], axis=1))
    parts = [floor, *walls]
    if box:
        # Half a sample inside the box faces, so no point sits on a cell boundary.
        bx = np.arange(1.7 + spacing / 2, 2.3, spacing)
        bz = np.arange(0.0, 0.5 + 1e-9, 0.05)
        gx, gy, gz = np.meshgrid(bx, bx - 0.5, bz)
        parts.append(np.stack([gx.ravel(), gy.ravel(), gz.ravel()], axis=1))
    parts.append(np.array([[3.0, 2.0, 2.2], [3.01, 2.0, 2.2]]))
    parts.append(np.array([[1.0, 2.5, 0.04], [1.02, 2.5, 0.04]]))
    return np.concatenate(parts, axis=0)


@pytest.fixture
def room_cloud() -> np.ndarray:
    """The room of :func:`room_points`, with its box."""
    return room_points()

