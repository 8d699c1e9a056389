"""Joint-space motion planning for an arm with OMPL and a pluggable validity test.

The state space is R^D with per-joint bounds (revolute joints are treated as bounded
intervals, not wrapped angles). Any collision model plugs in as ``is_valid(q) -> bool``; motions
are checked by sampling states at most ``resolution`` apart (Euclidean distance in joint space;
OMPL interpolates linearly between configurations), so obstacles thinner than what a joint step
of ``resolution`` sweeps can be missed.
"""

from __future__ import annotations

import logging
import time
from typing import Callable

import numpy as np

from planners._checks import as_float_array, check_seed, positive_float
from planners._ompl_backend import resolve_planner, solve
from planners.errors import PlannerInputError, PlannerTypeError
from planners.result import PlanResult

__all__ = ["plan_joint_path"]

_LOG = logging.getLogger(__name__)


def plan_joint_path(
    start_q,
    goal_q,
    lower,
    upper,
    is_valid: Callable[[np.ndarray], bool],
    *,
    time_limit: float = 1.0,
    seed: int = 0,
    planner: str = "rrtconnect",
    resolution: float = 0.01,
    simplify_time: float = 1.0,
) -> PlanResult:
    """Plan a collision-free joint-space path from ``start_q`` to ``goal_q``.

    ``is_valid`` receives a (D,) float64 array and returns True for a collision-free
    configuration; an exception it raises propagates to the caller. Start and goal outside the
    bounds are input errors (``ValueError``); a start or goal that ``is_valid`` rejects comes back
    as ``"start_in_collision"`` / ``"goal_in_collision"``; no path within ``time_limit`` comes
    back as ``"timeout"`` (joint space has no cheap reachability test, so ``"unreachable"`` is
    never claimed here). ``simplify_time`` caps the shortcutting of the found path (its work is
    also bounded by a fixed number of rounds); the same ``seed`` gives the same path unless
    planning or shortcutting is cut short by its time limit.

    Shape:
        start_q, goal_q, lower, upper: (D,) joint values (radians / metres), D >= 1.
        returns: PlanResult with path (N, D), N >= 2 when solved.
    """
    if not callable(is_valid):
        raise PlannerTypeError(f"is_valid: expected a callable, got {type(is_valid).__name__}")
    start = as_float_array("start_q", start_q, (None,))
    dim = len(start)
    if dim < 1:
        raise PlannerInputError("start_q: expected at least one joint, got shape (0,)")
    goal = as_float_array("goal_q", goal_q, (dim,))
    lo = as_float_array("lower", lower, (dim,))
    hi = as_float_array("upper", upper, (dim,))
    if not np.all(hi > lo):
        bad = np.flatnonzero(hi <= lo).tolist()
        raise PlannerInputError(f"lower/upper: expected lower < upper for every joint, violated at joints {bad}")
    for name, q in (("start_q", start), ("goal_q", goal)):
        out = np.flatnonzero((q < lo) | (q > hi))
        if len(out):
            raise PlannerInputError(f"{name}: joints {out.tolist()} lie outside [lower, upper]: {q[out].tolist()}")
    positive_float("time_limit", time_limit)
    positive_float("resolution", resolution)
    positive_float("simplify_time", simplify_time, allow_zero=True)
    seed = check_seed(seed)
    name = resolve_planner(planner)
    t0 = time.perf_counter()

    def result(status: str, reason: str, path=None, ran: str = "") -> PlanResult:
        path = np.zeros((0, dim)) if path is None else path
        _LOG.debug("joint plan %s: %s", status, reason)
        return PlanResult(status, reason, path, ran, time.perf_counter() - t0, seed)  # type: ignore[arg-type]

    if not is_valid(start.copy()):
        return result("start_in_collision", f"is_valid rejects the start configuration {start.tolist()}")
    if not is_valid(goal.copy()):
        return result("goal_in_collision", f"is_valid rejects the goal configuration {goal.tolist()}")

    outcome = solve(
        lower=lo,
        upper=hi,
        start=start,
        goal=goal,
        state_valid=lambda q: is_valid(np.asarray(q, dtype=np.float64)),
        planner=name,
        time_limit=time_limit,
        simplify_time=simplify_time,
        seed=seed,
        resolution=resolution,
    )
    if not outcome.solved:
        return result("timeout", outcome.reason, ran=name)
    return result("solved", outcome.reason, outcome.path, name)
