"""The outcome of one planning query, shared by the 2-D base planner and the joint-space planner."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal, get_args

import numpy as np

__all__ = ["PlanStatus", "PLAN_STATUSES", "PlanResult"]

PlanStatus = Literal["solved", "start_in_collision", "goal_in_collision", "unreachable", "timeout"]
"""What happened to a planning query.

* ``"solved"``: ``path`` runs from the start to the goal and every segment was checked.
* ``"start_in_collision"`` / ``"goal_in_collision"``: that configuration is invalid (inside an
  inflated obstacle, in unknown space treated as blocked, or outside the map/bounds).
* ``"unreachable"``: proven: start and goal lie in different connected parts of free space.
* ``"timeout"``: no path was found within the time limit; the goal may still be reachable.
"""

PLAN_STATUSES: tuple[str, ...] = get_args(PlanStatus)
"""Every value :data:`PlanStatus` can take."""


@dataclass(frozen=True, eq=False)
class PlanResult:
    """A planning outcome: a typed status, a human-readable reason and the path if solved.

    Shape:
        path: (N, D) float64 waypoints, first row the start and last row the goal, when
        ``status == "solved"``; (0, D) otherwise. D = 2 (x, y in metres, world frame) for the
        base planner and D = number of joints (radians or metres) for the joint planner.
    """

    status: PlanStatus
    """One of :data:`PLAN_STATUSES`."""
    reason: str
    """Why this status, in words (e.g. which cell the goal falls in)."""
    path: np.ndarray
    """Waypoints, see ``Shape``; read-only."""
    planner: str = ""
    """The planner name from the lookup table that ran (empty when OMPL was not called)."""
    planning_time_s: float = 0.0
    """Wall time spent in the planner and the path simplifier."""
    seed: int | None = field(default=None)
    """The seed the query ran with."""

    def __post_init__(self) -> None:
        if self.status not in PLAN_STATUSES:
            raise ValueError(f"status: expected one of {PLAN_STATUSES}, got {self.status!r}")
        path = np.array(self.path, dtype=np.float64, copy=True)
        if path.ndim != 2:
            raise ValueError(f"path: expected shape (N, D), got {path.shape}")
        path.setflags(write=False)
        object.__setattr__(self, "path", path)

    @property
    def solved(self) -> bool:
        """True when ``status == "solved"``."""
        return self.status == "solved"

    @property
    def length(self) -> float:
        """Sum of the Euclidean lengths of the path segments (0.0 when not solved)."""
        if len(self.path) < 2:
            return 0.0
        return float(np.linalg.norm(np.diff(self.path, axis=0), axis=1).sum())
