"""A language planner over any OpenAI-compatible chat-completions server (llama.cpp, vLLM, Ollama).

The paper's planner in the loop: the model is told it guides a home robot, given the eight
spatial comparators, the instruction, the room names and - only with a map - the objects the
map holds (:data:`PLANNER_PROMPT` and :func:`build_messages`), and answers in JSON::

    {"questions": [{"function": "howFar", "a": "sofa", "b": "coffee table"}],
     "goals": [{"phrase": "sofa", "room": "living room"}],
     "reasoning": "..."}

With a map it may ask questions first (``goals`` empty): the planner answers them with
``context.ask`` and sends the answers back in a follow-up user message, for up to
``max_rounds`` rounds of answers. Without a map questions are not allowed. A reply with goals
ends the exchange (questions asked alongside goals are not answered); one with neither goals nor
questions is a :class:`~agents.instruct.planner.Proposal` with no goals (explore).

Failure policy: never raises for what the server or the model does, never waits without bound.
A request that times out, is refused, answers an HTTP error or a body that is not a
chat-completions reply is retried up to ``max_retries`` times (as :mod:`agents.spatial.llm`, over
the same client, :mod:`agents.llm_http`); a reply the model wrote that cannot be used (not a JSON
object, no ``"goals"`` list, an unknown comparator, a question about an object not in the map or
without a map, a goal not in the allowed form, or a room not in the plan, still asking after
``max_rounds`` rounds) is not retried - at temperature 0 the same prompt gets the same answer -
and gives :func:`~agents.instruct.planner.planner_failure`'s Proposal with the reason, the
reasoning so far and the questions asked. At most ``(max_rounds + 1) * (1 + max_retries)``
requests, each bounded by ``timeout_s``.
"""

from __future__ import annotations

import json
import logging
import time
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from conceptfusion.errors import AgentError
from conceptfusion.spatial.comparators import COMPARATOR_NAMES
from conceptfusion.strict_json import loads_strict
from agents.instruct.proposal import GoalQuery, PlannerContext, Proposal, check_goal_query, planner_failure
from agents.llm_http import AttemptError, ReplyError, chat_reply_text, check_client_settings, request

__all__ = ["PLANNER_PROMPT", "ChatPlannerConfig", "ChatPlanner", "build_messages", "build_request_body"]

_log = logging.getLogger(__name__)

_MEANINGS = {
    "howFar": "the distance between a and b in metres (closest surfaces)",
    "isToTheRight": "true if a is to the right of b",
    "isToTheLeft": "true if a is to the left of b",
    "isContained": "true if a is inside b",
    "onTopOf": "true if a rests on top of b",
    "under": "true if a is underneath b",
    "isBigger": "true if a is bigger than b",
    "canFitInside": "true if a could fit inside b",
}

PLANNER_PROMPT = f"""You guide a robot that searches a home for objects. A person gives the robot an \
instruction; you decide which objects the robot should look for, and where.

You may be given the rooms of the home and the objects the robot's map holds so far. With such \
a list you can ask the map questions about two of its objects before you choose, using these \
functions:
{chr(10).join(f"{i}. {name}(a, b): {_MEANINGS[name]}" for i, name in enumerate(COMPARATOR_NAMES, 1))}

Reply with one JSON object and nothing else:
{{"questions": [{{"function": "...", "a": "...", "b": "..."}}], "goals": [{{"phrase": "...", "room": null}}], "reasoning": "..."}}
- "goals": what to search for, best first. A phrase is a short name of an object (letters, digits, \
spaces, hyphens, apostrophes; at most 60 characters). "room" is one of the rooms given, or null \
for anywhere.
- "questions": only when the map's objects are listed, and only about objects in that list. To \
ask, leave "goals" empty; the answers come back and you reply again in the same format. Without \
a list, never ask questions: give goals at once.
- "reasoning": one or two sentences on why.

Example.
Rooms: kitchen, living room, bedroom
Objects in the map:
- sofa (living room, at 1.0, 2.0)
- armchair (bedroom, at 6.5, 3.0)
- coffee table (living room, at 1.3, 1.4)
Instruction: I want to sit down next to the coffee table.
Reply: {{"questions": [{{"function": "howFar", "a": "sofa", "b": "coffee table"}}, \
{{"function": "howFar", "a": "armchair", "b": "coffee table"}}], "goals": [], \
"reasoning": "Both are seats; check which one is near the coffee table."}}
Answers from the map:
howFar(sofa, coffee table) -> 0.40 m
howFar(armchair, coffee table) -> 5.20 m
Reply: {{"questions": [], "goals": [{{"phrase": "sofa", "room": "living room"}}], \
"reasoning": "The sofa is 0.4 m from the coffee table; the armchair is in another room."}}"""
"""The planner's instructions and worked example (our own words, in the style of the paper's
planner prompt); :func:`build_messages` follows it with the rooms, objects and instruction."""


@dataclass(frozen=True)
class ChatPlannerConfig:
    """Where and how to reach the chat-completions server."""

    base_url: str
    """Server root including the API prefix, e.g. ``"http://127.0.0.1:8080/v1"``."""
    model: str = "default"
    """Model name sent in the request body (llama.cpp ignores it; vLLM and Ollama need the served name)."""
    api_key: str | None = None
    """Sent as a bearer token when set (printable ASCII, no whitespace); local servers usually need none."""
    timeout_s: float = 60.0
    """Upper bound on one request (one wall-clock deadline): connecting, sending, waiting, and
    reading the whole reply. At most 3600 s."""
    max_retries: int = 1
    """Further attempts at a request after a timeout, an HTTP 5xx/408/429 or an unreadable body
    (a reply the model wrote that cannot be used is not retried)."""
    retry_delay_s: float = 0.5
    """Pause between attempts (at most 3600 s)."""
    max_tokens: int = 512
    """Reply length cap per request."""
    temperature: float = 0.0
    """Sampling temperature (0: the same context gets the same plan)."""
    max_rounds: int = 2
    """Rounds of answered questions before the model must give goals (0: no questions)."""
    json_mode: bool = False
    """Also ask the server for a JSON reply (``response_format: {"type": "json_object"}``; llama.cpp,
    vLLM and Ollama honour it, some servers refuse it)."""
    max_reply_bytes: int = 1_000_000
    """Replies longer than this are rejected as garbage."""

    def __post_init__(self) -> None:
        check_client_settings(self)
        if isinstance(self.max_rounds, bool) or not isinstance(self.max_rounds, int) or self.max_rounds < 0:
            raise AgentError(f"max_rounds: expected an int >= 0, got {self.max_rounds!r}")
        if not isinstance(self.json_mode, bool):
            raise AgentError(f"json_mode: expected a bool, got {self.json_mode!r}")

    @property
    def url(self) -> str:
        """The chat-completions endpoint."""
        return self.base_url.rstrip("/") + "/chat/completions"

    @property
    def models_url(self) -> str:
        """The model list, which :meth:`ChatPlanner.check_server` reads."""
        return self.base_url.rstrip("/") + "/models"


def build_messages(instruction: str, context: PlannerContext) -> list[dict]:
    """The opening user turn: :data:`PLANNER_PROMPT`, the room names, the map's objects (only when
    ``context.has_map``) and the instruction."""
    lines = [PLANNER_PROMPT, "", "Now your task.", f"Rooms: {', '.join(context.rooms) if context.rooms else 'not known'}"]
    if context.has_map:
        lines.append("Objects in the map:" if context.objects else "Objects in the map: none yet")
        lines.extend(f"- {o.describe()}" for o in context.objects)
        if context.exhausted:
            lines.append("The robot has explored everything it can reach: choose the best of these objects, or no goal.")
    else:
        lines.append("No map: give goals from what homes usually hold; do not ask questions.")
    lines += [f"Instruction: {instruction.strip()}", "Reply:"]
    return [{"role": "user", "content": "\n".join(lines)}]


def build_request_body(config: ChatPlannerConfig, messages: list[dict]) -> dict:
    """The JSON body of one chat-completions request."""
    body = {"model": config.model, "messages": messages, "temperature": config.temperature,
            "max_tokens": config.max_tokens}
    if config.json_mode:
        body["response_format"] = {"type": "json_object"}
    return body


class _Unusable(AgentError):
    """A reply the model wrote that cannot be used; the message is the failure reason."""


def _format_answer(answer: bool | float | None, function: str) -> str:
    if answer is None:
        return "not found in the map"
    if isinstance(answer, (bool, np.bool_)):
        return "true" if answer else "false"
    return f"{float(answer):.2f} m" if function == "howFar" else f"{float(answer):.2f}"


def _reply_object(text: str) -> dict:
    """The JSON object in the model's text (a code fence or words around it tolerated)."""
    start, end = text.find("{"), text.rfind("}")
    if start < 0:
        raise _Unusable(f"reply is not a JSON object (got {_clip(text)})")
    candidate = text[start:end + 1] if end > start else text[start:]  # no closing brace: cut off at max_tokens?
    try:
        data = loads_strict(candidate, source="planner reply", error=ReplyError, allow_nan=False)
    except json.JSONDecodeError as err:
        raise _Unusable(f"reply is not JSON ({err.msg} at line {err.lineno} column {err.colno})") from None
    except ReplyError as err:
        raise _Unusable(f"reply refused: {err}") from None
    if not isinstance(data, dict):
        raise _Unusable(f"reply is not a JSON object (got a {type(data).__name__})")
    return data


def _clip(text: str, n: int = 60) -> str:
    return repr(text if len(text) <= n else text[:n] + "...")


def _read_goals(items: object, context: PlannerContext) -> tuple[GoalQuery, ...]:
    if not isinstance(items, list):
        raise _Unusable(f'reply has no "goals" list (got {type(items).__name__})')
    rooms = {r.lower(): r for r in context.rooms}
    goals = []
    for i, item in enumerate(items, 1):
        if isinstance(item, str):  # a bare phrase: anywhere
            item = {"phrase": item}
        if not isinstance(item, dict) or not isinstance(item.get("phrase"), str):
            raise _Unusable(f'goal {i}: expected {{"phrase": ..., "room": ...}}, got {_clip(json.dumps(item))}')
        room = item.get("room")
        if room is not None and not isinstance(room, str):
            raise _Unusable(f"goal {i}: room: expected null or a room name, got {_clip(json.dumps(room))}")
        room = room.strip() if room and room.strip() else None
        if room is not None and rooms:
            if room.lower() not in rooms:
                raise _Unusable(f"goal {i}: room {room!r} is not one of the rooms ({', '.join(context.rooms)})")
            room = rooms[room.lower()]
        try:
            goals.append(check_goal_query(GoalQuery(item["phrase"].strip(), room)))
        except ValueError as err:
            raise _Unusable(f"goal {i}: {err}") from None
    return tuple(goals)


def _read_questions(items: object, context: PlannerContext) -> list[tuple[str, str, str]]:
    if items is None:
        return []
    if not isinstance(items, list):
        raise _Unusable(f'reply "questions" is not a list (got {type(items).__name__})')
    if items and not context.has_map:
        raise _Unusable("questions asked without a map (only goals are allowed)")
    functions = {f.lower(): f for f in COMPARATOR_NAMES}
    objects = {o.name.lower(): o.name for o in context.objects}
    questions = []
    for i, item in enumerate(items, 1):
        if not isinstance(item, dict) or not all(isinstance(item.get(k), str) for k in ("function", "a", "b")):
            raise _Unusable(f'question {i}: expected {{"function": ..., "a": ..., "b": ...}}, got {_clip(json.dumps(item))}')
        function = functions.get(item["function"].strip().lower())
        if function is None:
            raise _Unusable(f"question {i}: unknown comparator {item['function']!r} (known: {', '.join(COMPARATOR_NAMES)})")
        args = []
        for key in ("a", "b"):
            name = objects.get(item[key].strip().lower())
            if name is None:
                raise _Unusable(f"question {i}: {item[key]!r} is not an object in the map")
            args.append(name)
        questions.append((function, args[0], args[1]))
    return questions


@dataclass(frozen=True)
class ChatPlanner:
    """A :class:`~agents.instruct.planner.LanguagePlanner` backed by a chat-completions server."""

    config: ChatPlannerConfig
    """Server address, timeout, retry policy and question rounds."""
    name: ClassVar[str] = "chat"
    """The backend's name in records."""

    def __post_init__(self) -> None:
        if not isinstance(self.config, ChatPlannerConfig):
            raise TypeError(f"config: expected a ChatPlannerConfig, got {type(self.config).__name__}")

    def check_server(self) -> tuple[str, ...]:
        """Read ``GET {base_url}/models`` once (bounded by ``timeout_s``); the model ids the server
        lists. Raises :class:`~conceptfusion.errors.AgentError` naming the URL when the server
        cannot be reached, refuses the key (HTTP 401/403), answers another error or no model list."""
        c = self.config
        url = c.models_url
        try:
            payload = request(url, body=None, api_key=c.api_key, timeout_s=c.timeout_s, max_reply_bytes=c.max_reply_bytes)
        except AttemptError as err:
            if err.status in (401, 403):
                key = "the api_key given" if c.api_key else "no api_key (none was set)"
                raise AgentError(f"chat server at {url} refused {key}: HTTP {err.status}") from None
            if err.status is not None:
                raise AgentError(f"chat server at {url} answered HTTP {err.status} "
                                 "(is base_url the API root, e.g. http://127.0.0.1:8080/v1?)") from None
            raise AgentError(f"chat server at {url} cannot be reached: {err.reason}") from None
        try:
            data = loads_strict(payload.decode("utf-8"), source=url, error=ReplyError)
            return tuple(str(m["id"]) for m in data["data"])
        except (UnicodeDecodeError, json.JSONDecodeError, ReplyError, KeyError, TypeError):
            raise AgentError(f"chat server at {url} answered something other than a model list "
                             '({"data": [{"id": ...}]}); is it an OpenAI-compatible server?') from None

    def propose(self, instruction: str, context: PlannerContext) -> Proposal:
        """Ask the server for goals for ``instruction`` (answering its questions with
        ``context.ask``); a Proposal with ``failure`` set on any failure."""
        if not isinstance(instruction, str):
            raise TypeError(f"instruction: expected a str, got {type(instruction).__name__}")
        if not isinstance(context, PlannerContext):
            raise TypeError(f"context: expected a PlannerContext, got {type(context).__name__}")
        if not instruction.strip():
            return planner_failure("empty instruction")
        messages = build_messages(instruction, context)
        asked: list[str] = []
        reasoning: list[str] = []

        def failed(reason: str) -> Proposal:
            _log.warning("chat planner failed for %r: %s", instruction, reason)
            return Proposal(reasoning="\n".join(reasoning), failure=reason, questions=tuple(asked))

        round_ = 0
        while True:
            round_ += 1
            text, error = self._send(messages)
            if error is not None:
                return failed(error)
            try:
                goals, questions = self._read_reply(text, context, reasoning)
            except _Unusable as err:
                return failed(f"unusable reply in round {round_}: {err}")
            if goals or not questions:
                return Proposal(goals=goals, reasoning="\n".join(reasoning), questions=tuple(asked))
            if round_ > self.config.max_rounds:
                return failed(f"still asking questions after {self.config.max_rounds} round(s) of answers "
                              f"(max_rounds={self.config.max_rounds})")
            answers = [f"{f}({a}, {b}) -> {_format_answer(context.ask(f, a, b), f)}" for f, a, b in questions]
            asked.extend(answers)
            messages = [*messages, {"role": "assistant", "content": text},
                        {"role": "user", "content": "Answers from the map:\n" + "\n".join(answers)
                         + "\nReply in the same JSON format."}]

    @staticmethod
    def _read_reply(text: str, context: PlannerContext, reasoning: list[str]) -> tuple[tuple[GoalQuery, ...], list]:
        """The goals and the questions (only when there are no goals) of one reply; its reasoning
        is appended to ``reasoning``. :class:`_Unusable` naming what is wrong."""
        reply = _reply_object(text)
        said = reply.get("reasoning")
        if said is not None and not isinstance(said, str):
            raise _Unusable(f'reply "reasoning" is not text (got {type(said).__name__})')
        if said and said.strip():
            reasoning.append(said.strip())
        if "goals" not in reply:
            raise _Unusable('reply has no "goals" list')
        goals = _read_goals(reply["goals"], context)
        return goals, ([] if goals else _read_questions(reply.get("questions"), context))

    def _send(self, messages: list[dict]) -> tuple[str, None] | tuple[None, str]:
        """The model's text, or None and why the server failed, after at most ``1 + max_retries``
        attempts."""
        c = self.config
        body = json.dumps(build_request_body(c, messages)).encode("utf-8")
        attempts = 1 + c.max_retries
        for attempt in range(1, attempts + 1):
            try:
                return chat_reply_text(request(c.url, body=body, api_key=c.api_key, timeout_s=c.timeout_s,
                                               max_reply_bytes=c.max_reply_bytes)), None
            except AttemptError as err:
                reason, retry = err.reason, err.retry
            _log.warning("chat planner request %d/%d to %s failed: %s", attempt, attempts, c.url, reason)
            if not retry:
                break
            if attempt < attempts and c.retry_delay_s > 0:
                time.sleep(c.retry_delay_s)
        return None, f"chat server failed after {attempt} attempt(s): {reason}"
