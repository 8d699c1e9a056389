"""What a language planner is told and what it answers: the data types of :mod:`agents.instruct.planner`.

Kept apart from the planner protocol and its lookup table so that the backends
(:mod:`agents.instruct.offline`, :mod:`agents.instruct.chat`) import these types without an
import circle through :func:`~agents.instruct.planner.make_planner`, which imports the backends;
:mod:`agents.instruct.planner` re-exports every name here.

* :class:`PlannerContext` - the room names, the objects the map holds (:class:`MapObject`) and
  ``ask(function, a, b)`` (None: no map context).
* :class:`Proposal` - ranked :class:`GoalQuery` s, the reasoning, or ``failure`` with the reason;
  :func:`planner_failure` builds a failed one, :func:`check_goal_query` checks a goal's form.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

__all__ = ["MAX_PHRASE", "MapObject", "GoalQuery", "PlannerContext", "Proposal", "planner_failure", "check_goal_query"]

MAX_PHRASE = 60
"""Longest goal phrase a planner may propose (characters)."""


@dataclass(frozen=True)
class MapObject:
    """One object the map holds, as the planner is told of it."""

    name: str
    """The vocabulary phrase that found it ("mug")."""
    position: tuple[float, float, float]
    """Median of its region's points (world frame, metres)."""
    room: str | None
    """The room of the floor plan it lies in (None: outside every room, or no plan)."""
    score: float = 1.0
    """How strongly the map answered ``name`` there (median relevancy score)."""

    def describe(self) -> str:
        x, y, _ = self.position
        return f"{self.name} ({self.room or 'no room'}, at {x:.1f}, {y:.1f})"


@dataclass(frozen=True)
class GoalQuery:
    """A goal to search for: a phrase the map is queried with, optionally only within one room."""

    phrase: str
    room: str | None = None

    def __str__(self) -> str:
        return self.phrase + (f" (in the {self.room})" if self.room else "")


@dataclass(frozen=True)
class PlannerContext:
    """What the planner is told besides the instruction (everything empty: no map context)."""

    rooms: tuple[str, ...] = ()
    """Room names of the labelled floor plan (the same for both agents)."""
    objects: tuple[MapObject, ...] = ()
    """The objects the map holds so far (map-context agent only)."""
    ask: Callable[[str, str, str], bool | float | None] | None = None
    """``ask(function, a, b)``: a comparator (one of
    :data:`~conceptfusion.spatial.comparators.COMPARATOR_NAMES`) on the map objects named ``a``
    and ``b``; a bool, a distance for ``howFar`` (m, closest surfaces), None when either is not in
    the map. None: no map to ask."""

    exhausted: bool = False
    """The agent has explored everything it can reach: choose the best the map holds now, or
    nothing (the search ends)."""

    @property
    def has_map(self) -> bool:
        return self.ask is not None


@dataclass(frozen=True)
class Proposal:
    """A planner's answer."""

    goals: tuple[GoalQuery, ...] = ()
    """Best first; empty: nothing to search for yet (explore) or a failure."""
    reasoning: str = ""
    """Why, in a few lines (kept in the record and shown in the replay)."""
    failure: str | None = None
    """Why the planner could not answer (a server timeout, a malformed reply, a goal not in the
    allowed form); None when it answered."""
    questions: tuple[str, ...] = ()
    """The spatial questions it asked the map, as ``function(a, b) -> answer``."""

    def __post_init__(self) -> None:
        if self.failure is not None and self.goals:
            raise ValueError("a failed Proposal has no goals")
        for g in self.goals:
            check_goal_query(g)


def check_goal_query(goal: GoalQuery) -> GoalQuery:
    """``goal`` when it is in the allowed form: a phrase of 1 to :data:`MAX_PHRASE` letters, digits,
    spaces, hyphens and apostrophes, and a room None or a non-empty string; else ``ValueError``
    naming what arrived."""
    if not isinstance(goal, GoalQuery):
        raise ValueError(f"goal: expected a GoalQuery, got {type(goal).__name__}")
    p = goal.phrase
    if not isinstance(p, str) or not 1 <= len(p.strip()) <= MAX_PHRASE or not all(c.isalnum() or c in " -'" for c in p):
        raise ValueError(f"goal phrase: expected 1 to {MAX_PHRASE} letters, digits, spaces, '-' or \"'\", got {p!r}")
    if goal.room is not None and (not isinstance(goal.room, str) or not goal.room.strip()):
        raise ValueError(f"goal room: expected None or a room name, got {goal.room!r}")
    return goal


def planner_failure(reason: str, reasoning: str = "") -> Proposal:
    """A :class:`Proposal` that says the planner failed, and why."""
    return Proposal(goals=(), reasoning=reasoning, failure=str(reason))
