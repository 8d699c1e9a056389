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

The data types live in :mod:`agents.instruct.proposal` (re-exported here): a backend imports them
from there, since this module imports the backends.
"""

from __future__ import annotations

from typing import Callable, Protocol

from conceptfusion.names import unknown_name_error
from agents.instruct.proposal import (MAX_PHRASE, GoalQuery, MapObject, PlannerContext, Proposal, check_goal_query,
                                      planner_failure)

__all__ = ["MAX_PHRASE", "MapObject", "GoalQuery", "PlannerContext", "Proposal", "LanguagePlanner", "PLANNERS",
           "make_planner", "planner_failure", "check_goal_query"]


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
