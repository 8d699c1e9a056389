"""The language planner interface: an instruction (and what the map holds) in, goals to search for out.

The paper's planner-in-the-loop setting: a language planner reads an instruction that names a
need, a place or a relation ("find something to eat in the kitchen") and answers with the
objects to look for. Without a map it answers from general knowledge alone; the map-context agent
also hands it the rooms and the objects its map holds so far and lets it ask the map spatial
questions (:mod:`conceptfusion.spatial.comparators`) before it chooses.

* :class:`PlannerContext` - what the planner is told: the room names of the labelled floor plan,
  the objects the map holds (:class:`MapObject`: the phrase that found it, where, which room) and
  ``ask(function, a, b)``, the comparators on two of those objects (None: no map context).
* :class:`Proposal` - its answer: ranked :class:`GoalQuery` s (a phrase to search the map for,
  optionally within one room), the reasoning kept in the record and the replay, or ``failure``
  with the reason (a server that timed out, a malformed reply) instead of goals.
* :class:`LanguagePlanner` - the protocol, ``propose(instruction, context) -> Proposal``;
  :data:`PLANNERS` / :func:`make_planner` build a backend by name (``"offline"``, the default that
  ships, :mod:`agents.instruct.offline`; ``"chat"``, an OpenAI-compatible server,
  :mod:`agents.instruct.chat`).

A planner never raises for what a server or a model says: a reply it cannot use is a
:class:`Proposal` with ``failure`` set, which the agent records as a planner failure.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Protocol

from conceptfusion.names import unknown_name_error

__all__ = ["MapObject", "GoalQuery", "PlannerContext", "Proposal", "LanguagePlanner", "PLANNERS", "make_planner",
           "planner_failure", "check_goal_query"]

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


class LanguagePlanner(Protocol):
    """``propose(instruction, context) -> Proposal``; ``name`` says which backend."""

    name: str

    def propose(self, instruction: str, context: PlannerContext) -> Proposal: ...


def _make_offline(**kwargs) -> LanguagePlanner:
    from agents.instruct.offline import OfflinePlanner, OfflinePlannerConfig

    return OfflinePlanner(OfflinePlannerConfig(**kwargs))


def _make_chat(**kwargs) -> LanguagePlanner:
    from agents.instruct.chat import ChatPlanner, ChatPlannerConfig

    return ChatPlanner(ChatPlannerConfig(**kwargs))


PLANNERS: dict[str, Callable[..., LanguagePlanner]] = {"offline": _make_offline, "chat": _make_chat}
"""Planner backends by name."""


def make_planner(name: str = "offline", **kwargs) -> LanguagePlanner:
    """Build the planner backend ``name`` with its options; an unknown name raises ``ValueError``
    naming the nearest valid ones, a bad option (a malformed server URL, say) before any episode."""
    if not isinstance(name, str):
        raise TypeError(f"name: expected a str, got {type(name).__name__}")
    factory = PLANNERS.get(name)
    if factory is None:
        raise unknown_name_error("language planner", name, PLANNERS, n=2, listing=f"valid: {', '.join(PLANNERS)}")
    return factory(**kwargs)
