"""The error hierarchy of the planners package.

Every error raised on purpose derives from :class:`PlannerError` and from the built-in class a
caller would expect (``ValueError`` or ``TypeError``), so ``except PlannerError`` and
``except ValueError`` both work. Planning *failures* (a goal inside an obstacle, no path in
time) are not errors: they come back as a :class:`planners.result.PlanResult` status.
"""

from __future__ import annotations

__all__ = [
    "PlannerError",
    "PlannerInputError",
    "PlannerTypeError",
    "UnknownPlannerError",
    "DegenerateGeometryError",
]


class PlannerError(Exception):
    """Base class of every error this package raises on purpose."""


class PlannerInputError(PlannerError, ValueError):
    """An argument has the wrong shape, a non-finite value or an out-of-range value."""


class PlannerTypeError(PlannerError, TypeError):
    """An argument has the wrong type or dtype."""


class UnknownPlannerError(PlannerError, ValueError):
    """A planner name is not in the lookup table; the message names the closest valid ones."""


class DegenerateGeometryError(PlannerError, ValueError):
    """A geometric construction is undefined (a zero-length line direction, a vertical line)."""
