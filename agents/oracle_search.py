"""A privileged scripted searcher for ``cf/ObjectSearch``: it reads the floor plan and the goal's
box from ``info`` at reset and proves the shipped episodes solvable. Not a fair baseline.

At reset it computes, over the free cells of the floor plan (already inflated by the robot's
radius), the geodesic distance to the cells that lie ``inset`` inside the success radius of the
goal's box, walks down that field from the start cell to get a path, and follows the path with
a carrot-following controller sized to the environment's control period: the carrot is the
farthest path point within ``lookahead`` metres that the base sees along free cells; the base
turns in place towards it, then drives straight to it. Where only the rim of the success region
is reachable, it aims closer to the rim. It stops once the distance to the goal that ``info``
reports is inside the success radius minus half the inset, or when the path is done. In a chain
(several goals revealed one at a time) it plans again from where it stopped for each goal revealed.
"""

from __future__ import annotations

import math

import numpy as np

from planners.geodesic import geodesic_field

__all__ = ["OracleSearchAgent", "descend"]


def descend(field_hw: np.ndarray, start_rc) -> list[tuple[int, int]]:
    """Cells from ``start_rc`` down the field to a cell where it is 0 (empty when the start has
    no finite value)."""
    h, w = field_hw.shape
    r, c = int(start_rc[0]), int(start_rc[1])
    if not (0 <= r < h and 0 <= c < w) or not np.isfinite(field_hw[r, c]):
        return []
    out = [(r, c)]
    while field_hw[r, c] > 0:
        best = min(((field_hw[r + dr, c + dc], r + dr, c + dc) for dr in (-1, 0, 1) for dc in (-1, 0, 1)
                    if (dr or dc) and 0 <= r + dr < h and 0 <= c + dc < w), default=(np.inf, r, c))
        if not best[0] < field_hw[r, c]:
            break
        r, c = best[1], best[2]
        out.append((r, c))
    return out


class OracleSearchAgent:
    """Privileged object search on the ground-truth floor plan; see the module docstring.

    Args:
        inset: metres inside the success radius that the path aims for and the stop waits for.
        lookahead: how far along the path (m) the carrot is looked for.
        control_dt: the environment's control period (s): a step's speed covers the carrot.
        max_linear, max_angular: command limits (m/s, rad/s).
        turn_angle: heading error (rad) above which the base turns in place.
    """

    privileged = True
    reads_images = False  # the floor plan, goal box and pose are all it reads: no camera needed

    def __init__(self, *, inset: float = 0.3, lookahead: float = 0.25, control_dt: float = 0.5, max_linear: float = 0.5,
                 max_angular: float = 1.5, turn_angle: float = 0.1) -> None:
        self.inset, self.lookahead, self.dt = float(inset), float(lookahead), float(control_dt)
        self.max_linear, self.max_angular, self.turn_angle = float(max_linear), float(max_angular), float(turn_angle)
        self.reset()

    def reset(self, *, seed: int | None = None) -> None:
        self._path: np.ndarray | None = None
        self._i = 0
        self._radius = 1.0
        self._inset = self.inset

    def _plan(self, observation, info: dict) -> None:
        if "free_grid" in info:  # at reset; a chain's later goals are planned on the same floor plan
            self._free = np.asarray(info["free_grid"], bool)
            self._origin, self._cell = np.asarray(info["grid_origin"], float), float(info["grid_cell"])
        free, origin, cell = self._free, self._origin, self._cell
        lo, hi = np.asarray(info["goal_aabb"], float)[:, :2]
        self._radius = float(info.get("success_distance", 1.0))
        h, w = free.shape
        xs = origin[0] + (np.arange(w) + 0.5) * cell
        ys = origin[1] + (np.arange(h) + 0.5) * cell
        dx = np.maximum(np.maximum(lo[0] - xs[None, :], 0), xs[None, :] - hi[0])
        dy = np.maximum(np.maximum(lo[1] - ys[:, None], 0), ys[:, None] - hi[1])
        pose = np.asarray(observation["base_pose"], float)
        c, r = np.floor((pose[:2] - origin) / cell).astype(int)
        cells = []
        # aim `inset` inside the success radius; closer to its edge when only that part is reachable
        for inset in (self.inset, self.inset / 2, cell, 0.0):
            field = geodesic_field(free, np.hypot(dx, dy) <= max(self._radius - inset, cell), cell)
            cells = descend(field, (r, c))
            if cells:
                self._inset = inset
                break
        pts = [pose[:2]] + [origin + (np.array([cc, rr]) + 0.5) * cell for rr, cc in cells[1:]]
        self._path = np.asarray(pts if len(pts) > 1 else [pose[:2], pose[:2] + 1e-3])
        self._i = 0

    def _clear(self, a, b) -> bool:
        """True when the segment a-b crosses only free cells (sampled every quarter cell)."""
        n = max(2, int(np.ceil(np.linalg.norm(b - a) / (self._cell / 4))) + 1)
        pts = a + np.linspace(0.0, 1.0, n)[:, None] * (b - a)
        c, r = np.floor((pts - self._origin) / self._cell).astype(int).T
        h, w = self._free.shape
        ok = (r >= 0) & (r < h) & (c >= 0) & (c < w)
        return bool(ok.all() and self._free[r, c].all())

    def act(self, observation, info: dict | None = None) -> np.ndarray:
        """Shape: returns (3,) float32 ``[linear, angular, stop]``."""
        if info is None:
            raise ValueError("OracleSearchAgent is privileged: act() needs the environment's info")
        if self._path is None or info.get("goal_reached"):  # a chain revealed its next goal (and its box)
            self._plan(observation, info)
        if float(info["distance_to_goal"]) <= self._radius - self._inset / 2:
            return np.array([0.0, 0.0, 1.0], np.float32)
        pose = np.asarray(observation["base_pose"], float)
        path = self._path
        # progress: the nearest waypoint at or after the last one, within a short window
        window = path[self._i : self._i + 20]
        self._i += int(np.argmin(np.linalg.norm(window - pose[:2], axis=1)))
        if self._i >= len(path) - 1 and np.linalg.norm(path[-1] - pose[:2]) < 0.1:
            return np.array([0.0, 0.0, 1.0], np.float32)
        ahead = np.cumsum(np.r_[0.0, np.linalg.norm(np.diff(path[self._i :], axis=0), axis=1)])
        j = self._i + int(min(np.searchsorted(ahead, self.lookahead), len(ahead) - 1))
        while j > self._i + 1 and not self._clear(pose[:2], path[j]):
            j -= 1  # the farthest carrot in sight: no corner of a doorway is cut
        if j > self._i and not self._clear(pose[:2], path[j]):
            j = self._i  # off the path's cell centres by a wall's corner: back to the nearest waypoint first
        dx, dy = path[j] - pose[:2]
        err = math.remainder(math.atan2(dy, dx) - pose[2], 2 * math.pi)
        turn = float(np.clip(err / self.dt, -self.max_angular, self.max_angular))
        if abs(err) > self.turn_angle:
            return np.array([0.0, turn, 0.0], np.float32)
        # straight towards the carrot (a curved step could leave the segment checked above);
        # the small heading error left is corrected by the next turn
        dist = math.hypot(dx, dy) * math.cos(err)
        return np.array([min(self.max_linear, dist / self.dt), 0.0, 0.0], np.float32)
