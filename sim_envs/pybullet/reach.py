"""Where the tabletop Panda can put its fingertip: a cached inverse-kinematics reachability test.

:class:`PandaReach` stands a kinematics twin (:class:`~sim_envs.pybullet.panda_kinematics.PandaKinematics`)
where :class:`~sim_envs.pybullet.tabletop.PyBulletTabletop` stands the arm for a table (centre
of the table's -y edge, 8 cm out, facing +y) and answers whether fingertip points are reachable
with the hand pointing down, as the push primitive needs them. Answers are cached on a 1 cm grid
(and per hand yaw), so generators can ask about many points cheaply. Used by the tabletop v2
episode generator to draw pushes inside the arm's reach.
"""

from __future__ import annotations

import math

import numpy as np

from sim_envs.pybullet.panda_kinematics import BASE_YAW, HOME_JOINTS, PandaKinematics
from sim_envs.scenes.format import Table

__all__ = ["PandaReach", "panda_base_position"]


def panda_base_position(table: Table) -> np.ndarray:
    """(3,) world position of the tabletop Panda's base for ``table`` (as the PyBullet backend)."""
    return np.array([table.center[0], table.center[1] - table.size[1] / 2 - 0.08, table.top_z])


class PandaReach:
    """Reachability of fingertip points for the Panda at ``table`` (see the module docstring).

    Args:
        table: the table the arm stands at.
        tol: largest IK position error (m) counted as reachable; below the backend's 1 cm
            ``reach_tol`` by default, for a margin.
        grid: cache cell size (m); a point is answered for its cell's centre.
    """

    def __init__(self, table: Table, *, tol: float = 0.005, grid: float = 0.01) -> None:
        import pybullet as p

        self.tol, self.grid = float(tol), float(grid)
        self._kin = PandaKinematics(panda_base_position(table), p.getQuaternionFromEuler([0.0, 0.0, BASE_YAW]), reach_tol=self.tol)
        self._euler = p.getQuaternionFromEuler
        self._cache: dict[tuple[int, int, int, int], bool] = {}

    @staticmethod
    def hand_yaw(direction_rad: float) -> float:
        """The hand yaw the backend uses for a push along ``direction_rad`` (narrow side leading)."""
        return BASE_YAW + ((direction_rad - BASE_YAW + math.pi / 2) % math.pi - math.pi / 2)

    def reachable(self, points_n3, direction_rad: float = 0.0) -> np.ndarray:
        """Whether the fingertip reaches each point with the hand set for a push along
        ``direction_rad``.

        Shape:
            points_n3: (n, 3) world points. returns: (n,) bool.
        """
        pts = np.asarray(points_n3, np.float64).reshape(-1, 3)
        yaw = self.hand_yaw(float(direction_rad))
        yaw_key = round(math.degrees(yaw)) % 180
        out = np.empty(len(pts), bool)
        for k, pt in enumerate(pts):
            cell = tuple(int(v) for v in np.round(pt / self.grid)) + (yaw_key,)
            hit = self._cache.get(cell)
            if hit is None:
                self._kin.down = self._euler([math.pi, 0.0, yaw])
                centre = np.asarray(cell[:3], np.float64) * self.grid
                hit = bool(self._kin.reach(centre, np.array(HOME_JOINTS))[1] <= self.tol)
                self._cache[cell] = hit
            out[k] = hit
        return out

    def close(self) -> None:
        """Disconnect the kinematics twin."""
        self._kin.close()
