"""Why an episode ended: one word per record (``extras["stop_reason"]``), from a fixed vocabulary.

The harness derives the word after the episode, from what the simulator knows (where the base
stopped, which objects moved, the step budget), never from what the agent says: it works the
same for any agent, a user's included, and no agent ever sees it. The words and their labels are
:data:`STOP_REASONS`; a record without the key (written before it existed) reads as unknown.

**Every task**: a record with status ``timeout`` is ``timeout`` and one with status ``failed`` is
``error`` (:func:`status_stop_reason`); a success is ``reached``.

**Instruction agents**: a failed search whose agent recorded that its language planner failed
(``extras["planner"]["failure"]``: a server timeout, a malformed reply) is ``planner_failure``, the
one word taken from what the agent records, since only it knows its planner failed.

**Object search** (:func:`search_stop_reason`, facts in :class:`SearchEnd`; a chain is judged on
the goal it was on when it ended). Distances are horizontal, from the base centre to an
object's footprint (the distance the environment scores success by), and ``r`` is its success
distance.

* The agent stopped (the episode terminated on ``stop``):

  1. ``wrong_object``: within ``r`` of another object, one that was out of reach (farther than
     ``r``) where the current goal's leg began (the episode start, or where the previous goal
     of a chain was reached): the base went to something that was not the goal;
  2. ``missed``: otherwise within :data:`NEAR_FACTOR` ``* r`` of the goal: it stopped near the
     goal but not close enough;
  3. ``not_found``: otherwise: it stopped away from the goal and from anything it approached
     (it gave up, or never committed to a target).

* The step budget ran out (the episode was truncated):

  1. ``wrong_object``: the base was parked (below) within ``r`` of another object it approached,
     as above: it hovered at the wrong object until the budget ran out;
  2. ``planner``: the base was stuck over the last :data:`STUCK_WINDOW` steps: it stayed within
     :data:`STUCK_RADIUS` of one place for the whole window ("parked", no progress), or at least
     :data:`STUCK_COLLISION_SHARE` of those steps collided;
  3. ``step_limit``: otherwise: it was still on its way.

  An episode shorter than :data:`STUCK_WINDOW` steps is never "parked" (a short budget is no
  evidence of being stuck), but its collisions count over the steps it has.

**Tabletop rearrangement** (:func:`rearrange_stop_reason`): an object "moved" when its box centre
ended at least :data:`MOVED_M` from where it started (horizontally).

1. ``not_found``: no object moved: the agent pushed nothing;
2. ``missed``: every target ended across the line (so another condition failed: a bystander moved
   :data:`~sim_envs.envs.rearrange_eval.DISTRACTOR_TOLERANCE` or more);
3. ``wrong_object``: no target moved, or the object that moved most is not a target;
4. ``missed``: otherwise: it pushed a target, which did not end across the line.

A tabletop episode is judged by its pushes whether it stopped or ran out of its few pushes, so it
never gets ``step_limit`` or ``planner``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = [
    "STOP_REASONS", "NEAR_FACTOR", "STUCK_WINDOW", "STUCK_RADIUS", "STUCK_COLLISION_SHARE", "MOVED_M", "SearchEnd", "SearchTrace",
    "search_stop_reason", "rearrange_stop_reason", "status_stop_reason", "box_distances_xy",
]

STOP_REASONS: dict[str, str] = {
    "reached": "reached the goal",
    "not_found": "never committed to a target (pushed nothing, or stopped away from all it approached)",
    "wrong_object": "went for another object than the goal",
    "missed": "got near the goal (or pushed it) but not far enough",
    "planner": "stuck: no progress, or colliding, over its last steps",
    "step_limit": "ran out of steps while still on its way",
    "planner_failure": "its language planner failed (a server timeout, a malformed reply; see the record's planner)",
    "timeout": "timed out (the harness's time limit)",
    "error": "crashed (an exception; see the error)",
}
"""Every stop reason: word (``extras["stop_reason"]``) -> short label for people."""

NEAR_FACTOR = 2.0
"""A search that stopped within this many success distances of its goal (and not next to
another object) ``missed`` it; farther, it is ``not_found``."""
STUCK_WINDOW = 25
"""Steps at the end of a truncated search that show whether the base was stuck (12.5 s at the
default 0.5 s per step: longer than a full look-around turn)."""
STUCK_RADIUS = 0.25
"""A base that stayed within this distance (m) of one place for :data:`STUCK_WINDOW` steps made
no progress (the default robot radius)."""
STUCK_COLLISION_SHARE = 0.5
"""A base that collided on at least this share of the last :data:`STUCK_WINDOW` steps was stuck."""
MOVED_M = 0.02
"""A tabletop object whose box centre ended at least this far (m, horizontally) from its start
was pushed (the untouched ones move well under a millimetre)."""


def status_stop_reason(status: str) -> str | None:
    """``timeout`` or ``error`` for a record of that status (``"timeout"``, ``"failed"``); None
    for ``"ok"`` (the episode ran: its task decides)."""
    reasons = {"timeout": "timeout", "failed": "error", "ok": None}
    if status not in reasons:
        raise ValueError(f"status: expected one of {sorted(reasons)}, got {status!r}")
    return reasons[status]


def box_distances_xy(xy, boxes_n23) -> np.ndarray:
    """Horizontal distance (m) from a point to each axis-aligned box's footprint (0 inside).

    Shape:
        xy: (2,). boxes_n23: (n, 2, 3) lower and upper corners (or (n, 2, 2)). returns: (n,).
    """
    boxes = np.asarray(boxes_n23, np.float64)
    if boxes.size == 0:
        return np.zeros(0)
    if boxes.ndim != 3 or boxes.shape[1] != 2 or boxes.shape[2] not in (2, 3):
        raise ValueError(f"boxes_n23: expected shape (n, 2, 3) or (n, 2, 2), got {boxes.shape}")
    p = np.asarray(xy, np.float64).reshape(2)
    gap = np.maximum(np.maximum(boxes[:, 0, :2] - p, 0.0), p - boxes[:, 1, :2])
    return np.linalg.norm(gap, axis=1)


@dataclass(frozen=True)
class SearchEnd:
    """What a finished search episode left, for :func:`search_stop_reason`.

    Shape:
        ``recent_xy`` (k, 2): the base's positions over the last ``min(STUCK_WINDOW, steps)``
        steps and the one before them (k <= STUCK_WINDOW + 1).
    """

    success: bool
    """The environment scored the episode a success."""
    stopped: bool
    """The agent's ``stop`` ended it (terminated); False: the step budget did (truncated)."""
    success_radius: float
    """The environment's success distance (m)."""
    goal_distance: float
    """Base to the current goal's footprint at the end (m)."""
    other_distance: float
    """Base to the nearest other object at the end (m), counting only objects that were farther
    than ``success_radius`` where the current goal's leg began; ``inf`` when there is none."""
    recent_xy: np.ndarray
    """The base's last positions (see Shape)."""
    recent_collisions: int
    """Collisions over the steps of ``recent_xy``."""


def _parked(end: SearchEnd) -> bool:
    xy = np.asarray(end.recent_xy, np.float64).reshape(-1, 2)
    if len(xy) < STUCK_WINDOW + 1:
        return False
    return bool(np.max(np.linalg.norm(xy - xy[-1], axis=1)) < STUCK_RADIUS)


def search_stop_reason(end: SearchEnd) -> str:
    """The stop reason of a finished search episode (rules: the module docstring)."""
    if not isinstance(end, SearchEnd):
        raise TypeError(f"end: expected a SearchEnd, got {type(end).__name__}")
    if end.success:
        return "reached"
    r = float(end.success_radius)
    if not (math.isfinite(r) and r > 0):
        raise ValueError(f"success_radius: expected a finite distance > 0, got {end.success_radius!r}")
    next_to_other = end.other_distance <= r
    if end.stopped:
        if next_to_other:
            return "wrong_object"
        return "missed" if end.goal_distance <= NEAR_FACTOR * r else "not_found"
    parked = _parked(end)
    if parked and next_to_other:
        return "wrong_object"
    steps = max(len(np.asarray(end.recent_xy).reshape(-1, 2)) - 1, 0)
    if parked or (steps and end.recent_collisions >= STUCK_COLLISION_SHARE * steps):
        return "planner"
    return "step_limit"


def rearrange_stop_reason(*, success: bool, displacement_n, target_n, targets_done) -> str:
    """The stop reason of a finished tabletop episode (rules: the module docstring).

    Args:
        displacement_n: each object's horizontal displacement from its start (m).
        target_n: True for the episode's targets.
        targets_done: per target, whether it ended across the line on its side.

    Shape:
        displacement_n, target_n: (n,) in the scene's object order. targets_done: (k,).
    """
    if success:
        return "reached"
    disp = np.asarray(displacement_n, np.float64).reshape(-1)
    target = np.asarray(target_n, bool).reshape(-1)
    if disp.shape != target.shape:
        raise ValueError(f"displacement_n and target_n: expected the same length (one per object), got {disp.shape[0]} "
                         f"and {target.shape[0]}")
    moved = disp >= MOVED_M
    if not moved.any():
        return "not_found"
    done = [bool(d) for d in targets_done]
    if done and all(done):
        return "missed"
    if not (moved & target).any() or not target[int(np.argmax(disp))]:
        return "wrong_object"
    return "missed"


class SearchTrace:
    """Follows a search episode step by step (the rollout's ``(observation, info)`` pairs, the
    reset's first) and builds its :class:`SearchEnd`: the objects' boxes from the reset's
    ``info["scene_graph"]``, the base from ``observation["base_pose"]``, the collisions and the
    current goal from ``info``. Evaluation-side only: nothing here reaches the agent."""

    def __init__(self) -> None:
        self._ids: list[str] = []
        self._boxes = np.zeros((0, 2, 3))
        self._success_radius = float("nan")
        self._recent: list[tuple[float, float, int]] = []
        self._leg: tuple | None = None
        self._leg_distances = np.zeros(0)

    @property
    def success_radius(self) -> float:
        """The environment's success distance (m), from the reset's ``info``; NaN before it."""
        return self._success_radius

    def observe(self, observation: dict, info: dict) -> None:
        """Take one step's (or the reset's) observation and info."""
        if "scene_graph" in info:
            objects = info["scene_graph"]["objects"]
            self._ids = [o["id"] for o in objects]
            self._boxes = np.array([o["aabb"] for o in objects], np.float64).reshape(-1, 2, 3)
        if "success_distance" in info:
            self._success_radius = float(info["success_distance"])
        xy = np.asarray(observation["base_pose"], np.float64)[:2]
        self._recent.append((float(xy[0]), float(xy[1]), int(info.get("collisions", 0))))
        del self._recent[:-(STUCK_WINDOW + 1)]
        leg = (info.get("goal_index", 0), bool(info.get("exploring", False)))
        if leg != self._leg:  # a new goal (or the end of exploring): its leg begins here
            self._leg = leg
            self._leg_distances = box_distances_xy(xy, self._boxes)

    def end(self, info: dict, *, truncated: bool) -> SearchEnd:
        """The :class:`SearchEnd` of the episode whose last step returned ``info``."""
        recent = np.array(self._recent, np.float64).reshape(-1, 3)
        xy = recent[-1, :2] if len(recent) else np.zeros(2)
        goal_id = info.get("goal_object_id")
        others = np.array([i != goal_id for i in self._ids], bool)
        if len(self._leg_distances) == len(others):
            others &= self._leg_distances > self._success_radius
        dist = box_distances_xy(xy, self._boxes[others])
        return SearchEnd(
            success=bool(info["success"]), stopped=not truncated, success_radius=self._success_radius,
            goal_distance=float(info["distance_to_goal"]), other_distance=float(dist.min()) if len(dist) else math.inf,
            recent_xy=recent[:, :2], recent_collisions=int(recent[-1, 2] - recent[0, 2]) if len(recent) else 0,
        )
