"""The error hierarchy of the planners package.

Every error raised on purpose derives from :class:`PlannerError` (the project's
:class:`conceptfusion.errors.PlannerError`, itself a ``ValueError`` under
:class:`~conceptfusion.errors.ConceptFusionError`) and from the built-in class a caller would
expect (``ValueError`` or ``TypeError``), so ``except PlannerError``, ``except ConceptFusionError``
and ``except ValueError`` all work. Planning *failures* (a goal inside an obstacle, no path in
time) are not errors: they come back as a :class:`planners.result.PlanResult` status.
"""

from __future__ import annotations

from conceptfusion.errors import PlannerError, UnknownNameError

__all__ = [
    "PlannerError",
    "PlannerInputError",
    "PlannerTypeError",
    "UnknownPlannerError",
    "DegenerateGeometryError",
]


class PlannerInputError(PlannerError, ValueError):
    """An argument has the wrong shape, a non-finite value or an out-of-range value."""


class PlannerTypeError(PlannerError, TypeError):
    """An argument has the wrong type or dtype (a ``TypeError``; as every :class:`PlannerError`,
    also a ``ValueError``)."""


class UnknownPlannerError(PlannerError, UnknownNameError):
    """A planner name is not in the lookup table; the message names the closest valid ones."""


class DegenerateGeometryError(PlannerError, ValueError):
    """A geometric construction is undefined (a zero-length line direction, a vertical line)."""
