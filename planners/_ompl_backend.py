"""OMPL plumbing shared by the base and joint-space planners: lookup table, seeding, solving.

OMPL (2.x Python bindings) is imported inside the functions that need it, so importing the
planners package costs nothing until a plan is requested.

Determinism: OMPL draws every planner's and simplifier's random seed from one process-wide
seed generator. :func:`solve` reseeds that generator before it builds anything, so the same
seed, problem and planner give the same path, as long as neither the planner nor the
simplifier stops on its time limit, the planner is single-threaded (not ``prm``/``prmstar``) and
no other thread plans with OMPL at the same time.
"""

from __future__ import annotations

import logging
import time
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Callable, Iterator

import numpy as np

from conceptfusion.names import unknown_name_error
from planners.errors import PlannerTypeError, UnknownPlannerError

__all__ = ["PLANNERS", "resolve_planner", "OmplOutcome", "solve"]

_LOG = logging.getLogger(__name__)

PLANNERS: dict[str, str] = {
    "rrtconnect": "RRTConnect",
    "rrt": "RRT",
    "rrtstar": "RRTstar",
    "informedrrtstar": "InformedRRTstar",
    "prm": "PRM",
    "prmstar": "PRMstar",
    "kpiece": "KPIECE1",
    "bitstar": "BITstar",
}
"""Planner names accepted by the planners of this package -> OMPL geometric class names.

Optimising planners (``rrtstar``, ``informedrrtstar``, ``prmstar``, ``bitstar``) stop at their
first exact solution unless asked to use the whole time limit. ``prm`` and ``prmstar`` grow
their roadmap in a second thread, so their paths are not reproducible from the seed."""


def resolve_planner(name: str) -> str:
    """Return the canonical lookup-table key for ``name`` (case and ``-``/``_``/``*`` ignored).

    Raises :class:`UnknownPlannerError` naming the closest valid names for an unknown name.
    """
    if not isinstance(name, str):
        raise PlannerTypeError(f"planner: expected a str, got {type(name).__name__}")
    key = _planner_key(name)
    if key in PLANNERS:
        return key
    raise unknown_name_error("planner", name, PLANNERS, cutoff=0.5, key=_planner_key,
                             listing=f"valid: {', '.join(PLANNERS)}", error=UnknownPlannerError)


def _planner_key(name: str) -> str:
    return name.strip().lower().replace("-", "").replace("_", "").replace("*", "star").replace(" ", "")


@dataclass(frozen=True)
class OmplOutcome:
    """What :func:`solve` found: an exact path or nothing, and why."""

    solved: bool
    """True when OMPL returned an exact solution that passed the final check."""
    reason: str
    """Why, in words."""
    path: np.ndarray
    """(N, D) waypoints, or (0, D) when not solved."""
    elapsed_s: float
    """Wall time in the planner and simplifier."""


def _import_ompl():
    from ompl import base as ob
    from ompl import geometric as og
    from ompl import util as ou

    return ob, og, ou


@contextmanager
def _log_level(ou, level) -> Iterator[None]:
    """OMPL's log level set to ``level`` (``None``: left as it is) inside the block, then restored."""
    previous = ou.getLogLevel()
    if level is not None:
        ou.setLogLevel(level)
    try:
        yield
    finally:
        ou.setLogLevel(previous)


def _seed_ompl(ou, seed: int) -> None:
    """Reseed OMPL's seed generator; OMPL needs a non-zero seed and complains on reseeding."""
    with _log_level(ou, ou.LogLevel.LOG_NONE):
        ou.RNG.setSeed(int(seed) % (2**31 - 1) + 1)


def _guarded(check: Callable[..., bool], errors: list[BaseException]) -> Callable[..., bool]:
    """``check`` as an OMPL callback: an exception it raises is kept in ``errors`` (to re-raise
    after OMPL returns; OMPL cannot carry it) and answers False, as does every call after it."""

    def guarded(*states) -> bool:
        if errors:
            return False
        try:
            return bool(check(*states))
        except BaseException as exc:
            errors.append(exc)
            return False

    return guarded


_MOTION_VALIDATOR_CLASS = None


def _motion_validator_class(ob):
    """A MotionValidator subclass that delegates to a Python segment check (built once)."""
    global _MOTION_VALIDATOR_CLASS
    if _MOTION_VALIDATOR_CLASS is None:

        class _CallbackMotionValidator(ob.MotionValidator):
            def __init__(self, si, segment_valid, dim):
                super().__init__(si)
                self._segment_valid = segment_valid
                self._dim = dim

            def checkMotion(self, s1, s2):  # noqa: N802 - OMPL's name
                d = self._dim
                return bool(self._segment_valid(s1[0:d], s2[0:d]))

        _MOTION_VALIDATOR_CLASS = _CallbackMotionValidator
    return _MOTION_VALIDATOR_CLASS


def solve(
    *,
    lower: np.ndarray,
    upper: np.ndarray,
    start: np.ndarray,
    goal: np.ndarray,
    state_valid: Callable[[list], bool],
    planner: str,
    time_limit: float,
    simplify_time: float,
    seed: int,
    segment_valid: Callable[[list, list], bool] | None = None,
    resolution: float | None = None,
    use_full_time: bool = False,
    planner_range: float | None = None,
) -> OmplOutcome:
    """Plan from ``start`` to ``goal`` in a box-bounded R^D with OMPL, then simplify.

    ``state_valid`` receives a state as a list of D floats. Motions are checked either by
    ``segment_valid(a, b)`` (exact, e.g. a grid traversal) or, when it is None, by OMPL sampling
    states ``resolution`` apart (same units as the state). ``planner`` is a canonical key of
    :data:`PLANNERS`. The final path is checked again segment by segment; a simplified path that
    fails the check is replaced by the raw planner path.

    Shape:
        lower, upper, start, goal: (D,) float64.
    """
    ob, og, ou = _import_ompl()
    # OMPL's default level (INFO) reports every query on stderr; keep warnings and errors.
    with _log_level(ou, None if _LOG.isEnabledFor(logging.DEBUG) else ou.LogLevel.LOG_WARN):
        dim = int(len(lower))
        _seed_ompl(ou, seed)

        space = ob.RealVectorStateSpace(dim)
        bounds = ob.RealVectorBounds(dim)
        for i in range(dim):
            bounds.setLow(i, float(lower[i]))
            bounds.setHigh(i, float(upper[i]))
        space.setBounds(bounds)
        si = ob.SpaceInformation(space)

        callback_error: list[BaseException] = []  # re-raised after solve
        state_check = _guarded(lambda state: state_valid(state[0:dim]), callback_error)  # kept alive while OMPL runs
        si.setStateValidityChecker(state_check)
        validator = None
        if segment_valid is not None:
            validator = _motion_validator_class(ob)(si, _guarded(segment_valid, callback_error), dim)
            si.setMotionValidator(validator)
        elif resolution is not None:
            extent = space.getMaximumExtent()
            si.setStateValidityCheckingResolution(min(1.0, max(resolution / extent, 1e-6)))
        si.setup()

        ss = og.SimpleSetup(si)
        s_state = si.allocState()
        g_state = si.allocState()
        for i in range(dim):
            s_state[i] = float(start[i])
            g_state[i] = float(goal[i])
        ss.setStartAndGoalStates(s_state, g_state)
        ompl_planner = getattr(og, PLANNERS[planner])(si)
        if planner_range is not None and hasattr(ompl_planner, "setRange"):
            ompl_planner.setRange(float(planner_range))
        ss.setPlanner(ompl_planner)

        objective = ob.PathLengthOptimizationObjective(si)
        if not use_full_time:
            # Any finite cost satisfies an infinite threshold: optimising planners stop at their
            # first exact path instead of refining it until the time limit.
            objective.setCostThreshold(ob.Cost(float("inf")))
        ss.setOptimizationObjective(objective)
        ss.setup()

        t0 = time.perf_counter()
        status = ss.solve(float(time_limit))
        plan_s = time.perf_counter() - t0
        if callback_error:
            raise callback_error[0]
        exact = bool(status) and ss.haveExactSolutionPath()
        if not exact:
            elapsed = time.perf_counter() - t0
            return OmplOutcome(
                False,
                f"{PLANNERS[planner]} found no exact path in {plan_s:.3f} s (limit {time_limit:g} s; OMPL: {status})",
                np.zeros((0, dim)),
                elapsed,
            )

        solution = ss.getSolutionPath()
        raw_solution = og.PathGeometric(solution)
        raw = _path_array(solution, dim)
        simplified = simplify_time > 0.0 and len(raw) > 2
        if simplified:
            _simplify(og, si, solution, time.perf_counter() + simplify_time)
        path = _path_array(solution, dim)
        ok = _path_ok(path, segment_valid, solution)
        if not ok and simplified and _path_ok(raw, segment_valid, raw_solution):
            _LOG.warning("simplified path failed the final check; returning the raw planner path")
            path, ok = raw, True
        if callback_error:
            raise callback_error[0]
        if not ok:
            return OmplOutcome(
                False,
                f"{PLANNERS[planner]} returned a path that fails the final motion check",
                np.zeros((0, dim)),
                time.perf_counter() - t0,
            )
        elapsed = time.perf_counter() - t0
        # Make the end points exact (OMPL copies them, but keep float round-off out of callers' way).
        path = path.copy()
        path[0], path[-1] = start, goal
        return OmplOutcome(True, f"{PLANNERS[planner]} found a path in {plan_s:.3f} s", path, elapsed)


_SIMPLIFY_ROUNDS = 5


def _simplify(og, si, path, deadline: float) -> None:
    """Shorten ``path`` in place with a bounded amount of work.

    Rounds of vertex reduction, partial shortcuts and collapsing close vertices, until a round
    changes nothing, after :data:`_SIMPLIFY_ROUNDS` rounds, or at ``deadline`` (checked between
    steps). Unlike OMPL's time-driven ``simplify``, the result does not depend on how fast the
    machine is unless the deadline cuts it short.
    """
    simplifier = og.PathSimplifier(si)
    for _ in range(_SIMPLIFY_ROUNDS):
        changed = False
        for step in (simplifier.reduceVertices, simplifier.partialShortcutPath, simplifier.collapseCloseVertices):
            if time.perf_counter() > deadline:
                _LOG.debug("path simplification stopped at its time limit")
                return
            changed = bool(step(path)) or changed
        if not changed:
            return


def _path_array(path, dim: int) -> np.ndarray:
    return np.array([path.getState(i)[0:dim] for i in range(path.getStateCount())], dtype=np.float64).reshape(-1, dim)


def _path_ok(path: np.ndarray, segment_valid, solution) -> bool:
    """Check every waypoint and every motion of a path (through the same checks OMPL used)."""
    if segment_valid is not None:
        return all(segment_valid(list(a), list(b)) for a, b in zip(path[:-1], path[1:]))
    return bool(solution.check())
