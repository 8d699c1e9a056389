"""What a tabletop simulation backend provides: the protocol the MuJoCo and PyBullet backends of
``TabletopRearrange`` both follow, so the environment, agents and scoring never see which one runs.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from conceptfusion.frames import RGBDFrame
from sim_envs.scenes.format import Scene

__all__ = ["PushOutcome", "TabletopSim", "PUSH_HEIGHT"]

PUSH_HEIGHT = 0.02
"""Fingertip height above the table top while pushing (metres)."""


@dataclass(frozen=True)
class PushOutcome:
    """What executing one push primitive did.

    Shape:
        ``fingertip_path`` (m, 3) world positions the fingertip passed through.
    """

    executed: bool
    """False when the arm could not reach or plan the push; then nothing moved."""
    reason: str
    """Empty when executed, otherwise why not."""
    contact: bool
    """The fingertip touched some object."""
    fingertip_path: np.ndarray


class TabletopSim(Protocol):
    """A tabletop scene loaded in a simulator, with a pusher or arm that executes push primitives."""

    scene: Scene

    def object_poses(self) -> np.ndarray:
        """(n, 7) float64: base-centre position xyz (world metres, z up) and quaternion wxyz of
        every object, rows in ``scene.objects`` order."""

    def object_aabbs(self) -> np.ndarray:
        """(n, 2, 3) world axis-aligned boxes (lower, upper corner) in the current state."""

    def push(self, start_xy, direction_rad: float, distance: float) -> PushOutcome:
        """Move the fingertip from above to ``start_xy`` at ``PUSH_HEIGHT`` over the table top
        without sweeping through objects, push in a straight line along ``direction_rad`` (world
        yaw) for ``distance`` metres, lift, and let the objects settle. Inputs are validated and
        clipped by the environment before they arrive here."""

    def render(
        self, eye, target, width: int, height: int, fovy_deg: float = 60.0, segmentation: bool = True
    ) -> RGBDFrame:
        """One posed RGB-D frame from ``eye`` looking at ``target``: OpenCV camera, metric depth,
        segmentation = index into ``scene.objects`` (-1 elsewhere)."""

    def close(self) -> None:
        """Release the simulator and renderer."""
