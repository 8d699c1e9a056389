"""Why an episode failed, in one word, for the report's failure pages and episode rows.

An episode records its cause in ``extras["stop_reason"]`` (one of :data:`RECORDED_CAUSES`). A
record without it (older runs) gets a coarse cause derived from its status and metrics by
:func:`failure_cause`: crashed and timed-out episodes by their status, object searches by the
final distance to the goal against the success radius and by their collisions, anything else
``unknown``. Map suites (no ``success`` metric) have no failures, only crashes and timeouts.
"""

from __future__ import annotations

import math

from harness.runner.stop_reasons import STOP_REASONS

__all__ = ["CAUSES", "RECORDED_CAUSES", "DERIVED_CAUSES", "DEFAULT_SUCCESS_RADIUS", "failure_cause", "cause_text",
           "is_scored", "is_failure", "success_radius", "goal_text"]

RECORDED_CAUSES = {**STOP_REASONS, "reached": "reached the goal (yet not scored a success)"}
"""The causes an episode records in ``extras["stop_reason"]``, with what each means."""

DERIVED_CAUSES = {
    "chain_partial": "reached some goals of the chain, not all (derived from goals_reached)",
    "near_no_stop": "ended within the success radius without stopping there (derived from distance_to_goal)",
    "stuck": "ended outside the success radius, colliding on most steps (derived from collisions)",
    "far": "ended outside the success radius (derived from distance_to_goal)",
    "unknown": "the record does not say why (no stop_reason, no distance to the goal)",
}
"""Coarse causes :func:`failure_cause` derives for records without ``stop_reason``."""

CAUSES = {**RECORDED_CAUSES, **DERIVED_CAUSES}
"""Every cause label, in the order the failure pages list them, with what it means."""

DEFAULT_SUCCESS_RADIUS = 1.0
"""Metres: the object-search environments' default ``success_distance``, used for records that
do not carry ``extras["success_radius"]``."""

_STUCK_FRACTION = 0.5
"""A search that collided on at least this fraction of its steps counts as ``stuck``."""


def _extras(record: dict) -> dict:
    extras = record.get("extras")
    return extras if isinstance(extras, dict) else {}


def _number(value) -> float | None:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    return float(value) if math.isfinite(value) else None


def is_scored(record: dict) -> bool:
    """Whether the record has a ``success`` metric (agent suites; the map suites have none)."""
    return isinstance((record.get("metrics") or {}).get("success"), bool)


def is_failure(record: dict) -> bool:
    """Crashed, timed out, or ``ok`` with ``success`` False (an ``ok`` record without a success
    metric is not a failure)."""
    if record.get("status") != "ok":
        return True
    return (record.get("metrics") or {}).get("success") is False


def success_radius(record: dict) -> tuple[float, bool]:
    """(the success radius in metres, whether the record carries it): ``extras["success_radius"]``
    when it is a positive number, else :data:`DEFAULT_SUCCESS_RADIUS`."""
    value = _number(_extras(record).get("success_radius"))
    if value is not None and value > 0:
        return value, True
    return DEFAULT_SUCCESS_RADIUS, False


def goal_text(record: dict) -> str | None:
    """The goal as the agent was told it (``extras["goal"]``), None when not recorded."""
    goal = _extras(record).get("goal")
    return goal.strip() if isinstance(goal, str) and goal.strip() else None


def failure_cause(record: dict) -> str | None:
    """The cause label (a key of :data:`CAUSES`, or an unlisted ``stop_reason`` as recorded) of a
    failed episode; None for one that did not fail (see :func:`is_failure`).

    Order: a ``timeout`` or ``failed`` status (``timeout``, ``error``); the recorded
    ``extras["stop_reason"]``; then derived: a chain that reached some of its goals
    (``chain_partial``); a final ``distance_to_goal`` within the success radius
    (``near_no_stop``) or outside it, colliding on at least half the steps (``stuck``) or not
    (``far``); otherwise ``unknown``.
    """
    if not isinstance(record, dict):
        raise TypeError(f"failure_cause: expected a results record (dict), got {type(record).__name__}")
    if not is_failure(record):
        return None
    status = record.get("status")
    if status == "timeout":
        return "timeout"
    if status != "ok":
        return "error"
    reason = _extras(record).get("stop_reason")
    if isinstance(reason, str) and reason.strip():
        return reason.strip()
    metrics = record.get("metrics") or {}
    reached, chain = _number(metrics.get("goals_reached")), _number(metrics.get("chain_length"))
    if reached is not None and chain is not None and 0 < reached < chain:
        return "chain_partial"
    distance = _number(metrics.get("distance_to_goal"))
    if distance is None:
        return "unknown"
    if distance <= success_radius(record)[0]:
        return "near_no_stop"
    steps, collisions = _number(metrics.get("steps")), _number(metrics.get("collisions"))
    if steps and collisions is not None and collisions >= _STUCK_FRACTION * steps:
        return "stuck"
    return "far"


def cause_text(label: str) -> str:
    """What a cause label means (an unlisted recorded ``stop_reason`` says so)."""
    return CAUSES.get(label, f"recorded stop_reason {label!r} (not one of {', '.join(RECORDED_CAUSES)})")
