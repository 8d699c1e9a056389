"""A privileged scripted pusher for ``cf/TabletopRearrange``: it reads ground-truth poses from
``info`` and proves the shipped episodes solvable. Not a fair baseline: it sees the state.

Per step: if every target is judged done (``info["evaluation"]``), stop. Otherwise take the first
unfinished target and choose a straight push that moves it ``aim`` past the line: candidate
directions fan out around the line's normal (0, +-10, ..., +-60 degrees); each candidate starts
behind the object (its far side from the goal), pushes through its centre, and travels far enough
to cross (:func:`planners.push.plan_push` gives the straight one's geometry). A candidate is kept
when its start point is on the table, the object's goal footprint stays on the table and the
swept corridor (object footprint swept along the push, plus the fingertip) keeps ``clearance``
from every other object's footprint (separating-axis test on oriented boxes). The smallest
deviation with a clear corridor wins. If none is clear, the target is first pushed along the line
(a sidestep, never back the way it came) into a lane from which a direct push is clear; failing
that, the direct push with the widest corridor. Pushes move an object at most ``max_travel``; the
next step re-reads the state, so a push that rotated or deflected the object is corrected.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planners.push import plan_push

__all__ = ["OraclePushAgent", "PushCandidate", "footprint_corners"]

_FINGER_RADIUS = 0.015
_MAX_DISTANCE = 0.5  # the action space's largest push


def _quat_to_mat(q) -> np.ndarray:
    w, x, y, z = np.asarray(q, float) / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def footprint_corners(pose, size) -> tuple[np.ndarray, np.ndarray]:
    """The object's oriented box (base at its origin) projected on the table, and the normals of
    the projection's edges (for separating-axis tests).

    Shape:
        pose: (7,) xyz + quaternion wxyz; size: (3,). returns corners (8, 2), axes (k, 2), k <= 3.
    """
    sx, sy, sz = np.asarray(size, float) / [2, 2, 1]
    local = np.array([[a * sx, b * sy, c * sz] for a in (-1, 1) for b in (-1, 1) for c in (0, 1)])
    R = _quat_to_mat(pose[3:7])
    corners = (local @ R.T + np.asarray(pose[:3]))[:, :2]
    axes = []
    for k in range(3):
        e = R[:2, k]
        if np.linalg.norm(e) > 1e-3:
            axes.append(np.array([-e[1], e[0]]) / np.linalg.norm(e))
    return corners, np.array(axes).reshape(-1, 2)


def _separation(a_pts, a_axes, b_pts, b_axes) -> float:
    """Largest gap along any candidate axis between two convex point sets (< 0: they overlap)."""
    gap = -np.inf
    for ax in np.concatenate([a_axes, b_axes]):
        pa, pb = a_pts @ ax, b_pts @ ax
        gap = max(gap, pb.min() - pa.max(), pa.min() - pb.max())
    return float(gap)


@dataclass(frozen=True)
class PushCandidate:
    """One straight push considered for a target."""

    start_xy: np.ndarray
    direction_rad: float
    distance: float
    deviation_rad: float
    clearance: float
    """Smallest gap between the swept corridor and any other object (m); < 0: it would hit one."""
    on_table: bool
    sidestep: bool = False
    """A move along the line into a clearer lane rather than across it."""

    def action(self) -> np.ndarray:
        return np.array([self.start_xy[0], self.start_xy[1], self.direction_rad, self.distance, 0.0], np.float32)


class OraclePushAgent:
    """Privileged scripted policy for ``cf/TabletopRearrange`` (reads ground truth from ``info``).

    Args:
        aim: how far past the line (m) each target's centre is pushed (success needs 0.02).
        clearance: gap (m) the swept corridor must keep from other objects.
        max_travel: longest distance (m) one push moves an object; longer moves take several
            pushes (a point pusher lets objects slip away over long pushes).
        approach: free travel (m) before the fingertip meets the object.
        deviations_deg: directions tried around the line's normal, in order of preference; those
            nearly along the line (> 78 degrees off) are sidesteps of ``sidestep`` metres that
            move a target into a clear lane when no direct push is clear.
        sidestep_lengths: sidestep lengths tried (shortest first) when looking for a lane from
            which a direct push is clear.
    """

    privileged = True
    reads_scan = False
    """It plans from the simulator's ground truth, never from the orbit scan."""

    def __init__(
        self,
        *,
        aim: float = 0.07,
        max_travel: float = 0.45,
        clearance: float = 0.025,
        approach: float = 0.04,
        deviations_deg: tuple[float, ...] = (0, 10, -10, 20, -20, 30, -30, 45, -45, 60, -60, 90, -90),
        sidestep: float = 0.1,
        sidestep_lengths: tuple[float, ...] = (0.05, 0.1, 0.15, 0.2),
    ) -> None:
        if aim <= 0.02:
            raise ValueError(f"aim: expected more than the 0.02 m success margin, got {aim}")
        self.sidestep = float(sidestep)
        self._sidesteps: dict[str, float] = {}
        self.sidestep_lengths = tuple(float(x) for x in sidestep_lengths)
        self.max_travel = min(float(max_travel), _MAX_DISTANCE - approach - 0.01)
        self.aim, self.clearance, self.approach = float(aim), float(clearance), float(approach)
        self.deviations = np.radians(np.asarray(deviations_deg, float))

    def reset(self, *, seed: int | None = None) -> None:
        """Forget the sidesteps of the last episode (every push is re-planned from ``info``)."""
        self._sidesteps: dict[str, float] = {}

    def act(self, observation, info: dict | None = None) -> np.ndarray:
        """Shape: returns (5,) float32 ``(start_x, start_y, direction_rad, distance, stop)``."""
        if info is None or "object_poses" not in info:
            raise ValueError("OraclePushAgent is privileged: expected the environment's info dict with ground truth, got none")
        done = info["evaluation"]["targets_done"]
        todo = [k for k, d in enumerate(done) if not d]
        if not todo:
            return np.array([0, 0, 0, 0, 1], np.float32)
        plans = {k: [c for c in self.candidates(info, k) if c.on_table] for k in todo}
        direct = {k: [c for c in plans[k] if not c.sidestep] for k in todo}
        for k in todo:  # 1. a direct push with a clear corridor
            for c in direct[k]:
                if c.clearance >= self.clearance:
                    return c.action()
        for k in todo:  # 2. a sidestep into a lane from which a direct push is clear
            c = self._sidestep_to_clear_lane(info, k)
            if c is not None:
                return self._remember(info, k, c)
        for k in todo:  # 3. a direct push with half the clearance, 4. any clear sidestep
            for c in direct[k]:
                if c.clearance >= self.clearance / 2:
                    return c.action()
        for k in todo:
            for c in plans[k]:
                if c.sidestep and c.clearance >= self.clearance and self._may_sidestep(info, k, c.deviation_rad):
                    return self._remember(info, k, c)
        fallback = [c for k in todo for c in direct[k]]  # 5. the widest corridor there is
        if not fallback:
            return np.array([0, 0, 0, 0, 1], np.float32)
        return max(fallback, key=lambda c: c.clearance).action()

    def _may_sidestep(self, info: dict, k: int, deviation: float) -> bool:
        """A target is never sidestepped back the way it last came (no oscillation)."""
        last = self._sidesteps.get(info["target_ids"][k])
        return last is None or np.sign(last) == np.sign(deviation)

    def _remember(self, info: dict, k: int, c: PushCandidate) -> np.ndarray:
        self._sidesteps[info["target_ids"][k]] = c.deviation_rad
        return c.action()

    def _sidestep_to_clear_lane(self, info: dict, k: int) -> PushCandidate | None:
        """The shortest clear push along the line after which a direct push would be clear."""
        ids = list(info["object_ids"])
        i = ids.index(info["target_ids"][k])
        for dist in self.sidestep_lengths:
            for dev in (np.pi / 2, -np.pi / 2):
                if not self._may_sidestep(info, k, dev):
                    continue
                step = self.candidates(info, k, deviations=(dev,), sidestep=dist)[0]
                if not step.on_table or step.clearance < self.clearance:
                    continue
                moved = dict(info)
                poses = np.array(info["object_poses"], float)
                poses[i, :2] += dist * np.array([np.cos(step.direction_rad), np.sin(step.direction_rad)])
                moved["object_poses"] = poses
                follow = [c for c in self.candidates(moved, k) if c.on_table and not c.sidestep]
                if any(c.clearance >= self.clearance for c in follow):
                    return step
        return None

    def candidates(self, info: dict, k: int, *, deviations=None, sidestep: float | None = None) -> list[PushCandidate]:
        """Every considered push for the ``k``-th target, in order of preference (``deviations``
        in radians and the ``sidestep`` length override the agent's)."""
        deviations = self.deviations if deviations is None else np.asarray(deviations, float)
        sidestep = self.sidestep if sidestep is None else float(sidestep)
        ids = list(info["object_ids"])
        sizes = np.asarray(info["object_sizes"], float)
        i = ids.index(info["target_ids"][k])
        side = info["target_sides"][k]
        poses = np.asarray(info["object_poses"], float)
        line = np.asarray(info["line"], float)
        view_dir = np.asarray(info.get("view_dir", (0.0, 1.0)), float)
        lo, hi = np.asarray(info["table_xy"], float)
        shapes = [footprint_corners(poses[j], sizes[j]) for j in range(len(ids))]
        corners, _ = shapes[i]
        centre = poses[i, :3] + _quat_to_mat(poses[i, 3:7])[:, 2] * sizes[i, 2] / 2  # box centre
        centre = centre[:2]
        straight = plan_push(
            np.array([centre[0], centre[1], 0.0]), line[0], line[1] - line[0], side,
            view_dir=view_dir, footprint_xy=corners,
        )
        normal = straight.push_direction[:2]
        past = straight.signed_distance
        out = []
        for dev in deviations:
            c, s = np.cos(dev), np.sin(dev)
            d = np.array([c * normal[0] - s * normal[1], s * normal[0] + c * normal[1]])
            v = np.array([-d[1], d[0]])
            along = float(d @ normal)
            travel = min(max(0.0, (self.aim - past) / along), self.max_travel) if along > 0.2 else sidestep
            rel = corners - centre
            back, front = float(np.max(-(rel @ d))), float(np.max(rel @ d))
            lat_lo, lat_hi = min(float(np.min(rel @ v)), -_FINGER_RADIUS), max(float(np.max(rel @ v)), _FINGER_RADIUS)
            start = centre - (back + _FINGER_RADIUS + self.approach) * d
            u0, u1 = -(back + 2 * _FINGER_RADIUS + self.approach), front + travel
            corridor = np.array([centre + a * d + b * v for a in (u0, u1) for b in (lat_lo, lat_hi)])
            axes = np.array([d, v])
            gaps = [_separation(corridor, axes, *shapes[j]) for j in range(len(ids)) if j != i]
            goal = corners + travel * d
            # the goal footprint keeps 2 cm from the table edges, or at least gets no closer to them
            lim_lo, lim_hi = np.minimum(lo + 0.02, corners.min(axis=0)), np.maximum(hi - 0.02, corners.max(axis=0))
            on_table = bool(
                np.all((start >= lo + 0.005) & (start <= hi - 0.005))
                and np.all((goal >= lim_lo - 1e-9) & (goal <= lim_hi + 1e-9))
            )
            out.append(PushCandidate(start, float(np.arctan2(d[1], d[0])), float(self.approach + travel + 0.01), float(dev),
                                     min(gaps) if gaps else np.inf, on_table, along <= 0.2))
        return out

    def plan(self, info: dict, k: int) -> PushCandidate | None:
        """The preferred push for the ``k``-th target alone: the first on-table candidate with a
        clear corridor (direct pushes first), else the direct one with the widest corridor
        (``None``: no candidate on the table)."""
        cands = [c for c in self.candidates(info, k) if c.on_table]
        for direct in (True, False):
            for c in cands:
                if c.sidestep != direct and c.clearance >= self.clearance:
                    return c
        direct_cands = [c for c in cands if not c.sidestep]
        return max(direct_cands, key=lambda c: c.clearance) if direct_cands else None
