"""The planner-in-the-loop agents: an instruction, a language planner, and the map navigator.

Both agents drive the same :class:`~agents.navigator.MapNavigator` (same perception, map,
frontiers, OMPL planner, stop and presume rules) and are told the same labelled floor plan
(``room_plan``: room outlines and names). They differ only in what the language planner
(:mod:`agents.instruct.planner`) is given:

* **generic** (``use_map_context=False``, the paper's planner without a map): the planner reads
  the instruction alone, once, and proposes goals from general knowledge; the agent searches for
  its first proposal (the map answers the phrase, within the proposal's room when it names one)
  and, when the navigator has explored everything without finding it, for the next.
* **map context** (``use_map_context=True``, the paper's ConceptFusion planner): while it explores,
  every :attr:`InstructionAgentConfig.replan_every` steps in which the map grew, the agent lists
  the objects its map holds (it asks the map for every phrase of the planner's vocabulary in one
  batch, :meth:`~conceptfusion.mapper.ConceptMapper.present`, and keeps those found, each with its
  room and region) and hands them to the planner with ``ask``, the spatial comparators on those
  regions. The planner's first goal is searched for as above; with no goal yet it explores on.

A planner that fails (a server timeout, a malformed reply) ends the episode at once with a stop
and the reason in the record (``extras["planner"]["failure"]``, stop reason ``planner_failure``).
What each call proposed and why is kept (:meth:`InstructionAgent.record_extras`), as is the time
the planner calls and the map listings took.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from agents.instruct.planner import LanguagePlanner
from agents.instruct.proposal import GoalQuery, MapObject, PlannerContext, Proposal
from agents.navigator import MapNavigator, search_action
from conceptfusion.map.query import QueryResult
from conceptfusion.map.regions import Region
from conceptfusion.spatial.comparators import closest_distance, get_comparator
from conceptfusion.tasks import rooms_from_plan

__all__ = ["InstructionAgentConfig", "InstructionAgent", "map_phrase", "MAX_KEPT_CALLS"]

MAX_KEPT_CALLS = 12
"""Planner calls whose reasoning a record keeps in full (the first ones and the last; the count is
always kept)."""


@dataclass(frozen=True)
class InstructionAgentConfig:
    """Settings of :class:`InstructionAgent`."""

    use_map_context: bool = True
    replan_every: int = 8
    """Map context: steps between planner calls (a call is made only when frames were fused since
    the last one)."""

    def __post_init__(self) -> None:
        if not isinstance(self.use_map_context, bool):
            raise ValueError(f"use_map_context: expected a bool, got {self.use_map_context!r}")
        if isinstance(self.replan_every, bool) or not isinstance(self.replan_every, int) or self.replan_every < 1:
            raise ValueError(f"replan_every: expected an integer >= 1, got {self.replan_every!r}")


def map_phrase(name: str) -> str:
    """The phrase a map is asked for a category or goal phrase ("mug" -> "the mug")."""
    name = name.strip()
    return name if name.split(" ", 1)[0] in ("the", "a", "an", "something", "somewhere") else f"the {name}"


def _room_of(xy, rooms) -> str | None:
    for name, box in rooms:
        if box[0] <= xy[0] <= box[2] and box[1] <= xy[1] <= box[3]:
            return name
    return None


def _not_found(reason: str) -> QueryResult:
    empty = np.zeros(0, np.float32)
    return QueryResult(False, [], empty, empty, empty, reason=reason)


class InstructionAgent:
    """Planner-in-the-loop searcher (see the module doc).

    Args:
        navigator: the map navigator it drives (its mapper is the agent's map).
        planner: the language planner.
        config: see :class:`InstructionAgentConfig`.
    """

    def __init__(self, navigator: MapNavigator, planner: LanguagePlanner,
                 config: InstructionAgentConfig = InstructionAgentConfig()) -> None:
        self.nav, self.planner, self.config = navigator, planner, config
        self.privileged = navigator.privileged
        self.nav.locator = self._locate
        self.reset()

    @property
    def mapper(self):
        return self.nav.mapper

    def reset(self, *, seed: int | None = None) -> None:
        self.nav.reset(seed=seed)
        self._instruction: str | None = None
        self._rooms: list = []
        self._goals: tuple[GoalQuery, ...] = ()
        self._goal_k = 0
        self._steps = 0
        self._last_plan_step: int | None = None
        self._last_plan_frames = -1
        self._failure: str | None = None
        self._asked_exhausted = False
        self._calls: list[dict] = []
        self._planner_s = 0.0
        self._context_s = 0.0
        self._objects: dict[str, tuple[MapObject, Region]] = {}

    # -- what the planner is told -------------------------------------------------------------

    def _list_map(self) -> tuple[MapObject, ...]:
        """Ask the map for every vocabulary phrase; keep what it finds (with its region's answer)."""
        from agents.instruct.offline import planner_vocabulary

        t0 = time.perf_counter()
        found: dict[str, tuple[MapObject, Region]] = {}
        names = planner_vocabulary()[0]
        regions = self.mapper.present([map_phrase(n) for n in names])
        for name in names:
            region = regions.get(map_phrase(name))
            if region is not None:
                pos = tuple(float(v) for v in np.median(region.points_n3, axis=0))
                score = float(np.median(region.scores_n))
                found[name] = (MapObject(name, pos, _room_of(pos[:2], self._rooms), score), region)
        self._objects = found
        self._context_s += time.perf_counter() - t0
        return tuple(o for o, _ in found.values())

    def _ask(self, function: str, a: str, b: str) -> bool | float | None:
        """A comparator on two listed map objects (None: either is not in the map, or undecided)."""
        if a not in self._objects or b not in self._objects:
            return None
        ra, rb = self._objects[a][1], self._objects[b][1]
        answer = closest_distance(ra, rb) if function == "howFar" else get_comparator(function)(ra, rb)
        return answer.value

    def _context(self, exhausted: bool = False) -> PlannerContext:
        rooms = tuple(name for name, _ in self._rooms)
        if not self.config.use_map_context:
            return PlannerContext(rooms=rooms)
        return PlannerContext(rooms=rooms, objects=self._list_map(), ask=self._ask, exhausted=exhausted)

    def _call_planner(self, exhausted: bool = False) -> Proposal:
        context = self._context(exhausted)
        t0 = time.perf_counter()
        proposal = self.planner.propose(self._instruction, context)
        self._planner_s += time.perf_counter() - t0
        self._last_plan_step, self._last_plan_frames = self._steps, self.mapper.map.frames_integrated
        self._calls.append({"step": self._steps, "goals": [str(g) for g in proposal.goals], "reasoning": proposal.reasoning,
                            "questions": list(proposal.questions), **({"failure": proposal.failure} if proposal.failure else {}),
                            "objects": len(context.objects)})
        if proposal.failure:
            self._failure = proposal.failure
            self.nav._note(f"planner failed: {proposal.failure}")
        elif [str(g) for g in proposal.goals] != [str(g) for g in self._goals]:
            self.nav._note("planner: " + (", ".join(str(g) for g in proposal.goals) or "nothing fits yet, explore"))
            self._goals, self._goal_k = proposal.goals, 0
        return proposal

    # -- the navigator's goal ------------------------------------------------------------------

    def _current(self) -> GoalQuery | None:
        return self._goals[self._goal_k] if self._goal_k < len(self._goals) else None

    def _locate(self, _goal_text: str, presume: bool) -> QueryResult:
        """The navigator's answer for its goal: the planner's current goal in the map, within its room."""
        if self.config.use_map_context and self._failure is None:
            due = self._last_plan_step is None or (self._steps - self._last_plan_step >= self.config.replan_every
                                                   and self.mapper.map.frames_integrated != self._last_plan_frames)
            if due:
                self._call_planner()
        goal = self._current()
        if goal is None:
            return _not_found("the planner has no goal yet")
        phrase = map_phrase(goal.phrase)
        res = self.mapper.locate_present(phrase) if presume and goal.room is None else self.mapper.locate(phrase)
        if res.found and goal.room is not None:
            boxes = [box for name, box in self._rooms if name == goal.room]
            kept = [r for r in res.regions if boxes and _room_of(np.median(r.points_n3[:, :2], axis=0), [(goal.room, boxes[0])])]
            if not kept:
                return _not_found(f"'{phrase}' is in the map, but not in the {goal.room}")
            res = QueryResult(True, kept, res.scores_n, res.relative_n, res.relevancy_n, reason=res.reason, extras=res.extras)
        return res

    # -- protocol --------------------------------------------------------------------------------

    def act(self, observation, info: dict | None = None) -> np.ndarray:
        if self._instruction is None:
            self._instruction = str(observation["goal"])
            self._rooms = rooms_from_plan(observation)
            if not self.config.use_map_context:
                self._call_planner()
        if self._failure is not None:
            return search_action(stop=True)
        obs = dict(observation)
        obs["goal"] = self._instruction  # the navigator's goal text never changes: the agent answers it
        action = self.nav.act(obs, info)
        self._steps += 1
        if self.nav.gave_up and self._failure is None:
            if not self.config.use_map_context and self._goal_k + 1 < len(self._goals):
                self._goal_k += 1
                self.nav._note(f"nothing left to explore for '{self._goals[self._goal_k - 1]}': next proposal '{self._current()}'")
            elif self.config.use_map_context and not self._asked_exhausted:
                self._asked_exhausted = True  # once: choose the best the map holds, or end here
                if not self._call_planner(exhausted=True).goals:
                    return action
            else:
                return action
            self.nav.gave_up = False
            self.nav._next_goal(self._instruction)
            return search_action(0.0, self.nav.config.look_angular)
        if self._failure is not None:
            return search_action(stop=True)
        return action

    def record_extras(self) -> dict:
        """What the record keeps of the planner: its backend, calls (the first and last
        :data:`MAX_KEPT_CALLS` in full), the goal searched for last, a failure's reason, and the
        time (s) of the planner calls and of listing the map for them."""
        calls = self._calls
        kept = calls if len(calls) <= MAX_KEPT_CALLS else calls[: MAX_KEPT_CALLS // 2] + calls[-MAX_KEPT_CALLS // 2:]
        current = self._current()
        return {"planner": {
            "backend": getattr(self.planner, "name", type(self.planner).__name__), "map_context": self.config.use_map_context,
            "calls": len(calls), "kept_calls": kept, "final_goal": str(current) if current else None,
            "failure": self._failure, "planner_s": round(self._planner_s, 4), "context_s": round(self._context_s, 4),
        }}
