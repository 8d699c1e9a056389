"""The offline language planner: the shipped MiniLM text tower and the spatial comparators, no LLM.

What it is: a small rule-reader and a ranking. It reads an instruction of the forms the
instruction episodes use (:mod:`sim_envs.scenes.instruct_episodes`) and their near paraphrases:

    [lead-in] WHAT [in|from the ROOM | in the room with the MARK] | WHAT REL the ANCHOR

with lead-ins such as "I need", "find", "take me to"; ``REL`` one of next to / near / beside /
on / on top of / in / inside / under. ``WHAT`` ("something to eat", "the toy", "something") is
ranked against the object vocabulary it knows (:func:`planner_vocabulary`: the object library's
categories, each with its name, synonyms, function phrases and taxonomy groups, shipped as
:data:`VOCABULARY_FILE`) by cosine
similarity of MiniLM sentence embeddings; "something" alone ranks nothing (any object).

Without map context (the generic planner) it proposes the :attr:`OfflinePlannerConfig.top_k`
best-ranked categories, in the named room if any; a room given by a piece of furniture ("the
room with the sofa") is guessed from the furniture's name against the room names; a relation is
answered with its anchor, the one object it can name (then its best-ranked categories for
``WHAT``). With map context it chooses among the
objects the map holds: those in the room (named, or where the map saw the ``MARK``), those that
the comparators say stand in the relation to the anchor (``onTopOf``, ``isContained``, ``under``,
``howFar`` within :attr:`OfflinePlannerConfig.near_m`), and, when ``WHAT`` names something, only
categories within :attr:`~OfflinePlannerConfig.fit_margin` of the best similarity (once
everything is explored, any among the :attr:`~OfflinePlannerConfig.context_rank` best-ranked);
nothing fits yet means no goal (the agent explores on and asks again).

What it cannot do: read instructions outside these forms (it proposes the best-ranked categories
for the whole sentence then), reason about quantities, negation or sequences, or know objects
outside its vocabulary; it never guesses which of two rooms a piece of furniture stands in
without a map.
"""

from __future__ import annotations

import functools
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from agents.instruct.proposal import GoalQuery, PlannerContext, Proposal, planner_failure

__all__ = ["OfflinePlanner", "OfflinePlannerConfig", "VOCABULARY_FILE", "ParsedInstruction", "parse_instruction", "planner_vocabulary",
           "RELATIONS", "ROOM_NAMES"]

ROOM_NAMES = ("kitchen", "living room", "study", "bedroom", "bathroom", "dining room", "hallway", "office")
"""Room names the reader recognises after "in the" / "from the"."""

RELATIONS = {"next to": "near", "near": "near", "beside": "near", "close to": "near", "on top of": "on", "on": "on",
             "inside": "in", "in": "in", "under": "under", "underneath": "under", "below": "under"}
"""Relation words -> the relation read."""

_COMPARATOR = {"on": "onTopOf", "in": "isContained", "under": "under"}
_LEAD = re.compile(r"^(?:please |hey |robot,? )*(?:i need|i want|i am looking for|find(?: me)?|take me to|go to|bring me(?: to)?|"
                   r"get me|show me|where is|where can i find|look for|search for|fetch)\s+")
_ANY = frozenset({"something", "anything", "thing", "the thing", "the object", "an object", "object", "one", "it"})
_TEXT_ENCODER = "minilm-text"


@dataclass(frozen=True)
class OfflinePlannerConfig:
    """Settings of :class:`OfflinePlanner` (fixed before any instruction episode ran; not tuned on them)."""

    top_k: int = 3
    """Categories the generic planner proposes, best first."""
    fit_margin: float = 0.1
    """With map context, an object of the map fits ``WHAT`` when its category's similarity is within
    this of the best any category reaches: the planner goes for it at once."""
    context_rank: int = 5
    """Once the agent has explored everything (``PlannerContext.exhausted``), an object of the map
    whose category is among this many best-ranked is taken as the best there is."""
    near_m: float = 0.75
    """"Next to": the comparators' closest-surface distance at most this (metres)."""

    def __post_init__(self) -> None:
        for name in ("top_k", "context_rank"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ValueError(f"{name}: expected an integer >= 1, got {v!r}")
        if not isinstance(self.near_m, (int, float)) or isinstance(self.near_m, bool) or not 0 < self.near_m < 10:
            raise ValueError(f"near_m: expected a number in (0, 10) metres, got {self.near_m!r}")
        if not isinstance(self.fit_margin, (int, float)) or isinstance(self.fit_margin, bool) or not 0 <= self.fit_margin <= 2:
            raise ValueError(f"fit_margin: expected a number in [0, 2], got {self.fit_margin!r}")


@dataclass(frozen=True)
class ParsedInstruction:
    """What the reader made of an instruction."""

    what: str
    """The wanted thing with lead-in and articles removed ("" for "something")."""
    room: str | None = None
    """A named room."""
    room_mark: str | None = None
    """The furniture or object that singles the room out ("the room with the sofa")."""
    relation: str | None = None
    """``near``, ``on``, ``in`` or ``under``."""
    anchor: str | None = None
    """The object of the relation."""


def _strip_article(text: str) -> str:
    text = text.strip()
    for art in ("the ", "a ", "an ", "some "):
        if text.startswith(art):
            return text[len(art):]
    return text


def parse_instruction(instruction: str) -> ParsedInstruction:
    """Read ``instruction`` (see the module doc); ``ValueError`` for an empty one."""
    if not isinstance(instruction, str):
        raise TypeError(f"instruction: expected a str, got {type(instruction).__name__}")
    text = re.sub(r"\s+", " ", instruction.lower().strip().rstrip(".!?")).strip()
    if not text:
        raise ValueError("instruction: expected words, got an empty string")
    text = _LEAD.sub("", text)
    m = re.fullmatch(r"(?P<what>.+?) (?:in|from) the room with the (?P<mark>.+)", text)
    if m:
        return ParsedInstruction(_head(m["what"]), room_mark=_strip_article(m["mark"]))
    m = re.fullmatch(rf"(?P<what>.+?) (?:in|from) the (?P<room>{'|'.join(ROOM_NAMES)})(?: room)?", text)
    if m:
        return ParsedInstruction(_head(m["what"]), room=m["room"])
    words = "|".join(sorted(RELATIONS, key=len, reverse=True))
    m = re.fullmatch(rf"(?P<what>.+?) (?P<rel>{words}) (?P<anchor>(?:the |a |an ).+)", text)
    if m:
        return ParsedInstruction(_head(m["what"]), relation=RELATIONS[m["rel"]], anchor=_strip_article(m["anchor"]))
    return ParsedInstruction(_head(text))


def _head(what: str) -> str:
    what = what.strip()
    return "" if what in _ANY else _strip_article(what)


VOCABULARY_FILE = Path(__file__).with_name("vocabulary.json")
"""The categories the planner knows, written from the object library (``python -m harness.planner_vocabulary``)."""


@functools.lru_cache(maxsize=1)
def planner_vocabulary() -> tuple[tuple[str, ...], tuple[tuple[str, ...], ...]]:
    """The categories the planner knows and, per category, the texts it is ranked by (its name,
    synonyms, function phrases and "a <group>" for each taxonomy group above it), from
    :data:`VOCABULARY_FILE`."""
    from conceptfusion.io_utils import read_json_file

    data = read_json_file(VOCABULARY_FILE, "planner vocabulary", ValueError)
    cats = data.get("categories") if isinstance(data, dict) else None
    if data.get("format") != "cf-planner-vocabulary" or not isinstance(cats, dict) or not cats or not all(
            isinstance(v, list) and v and all(isinstance(t, str) and t for t in v) for v in cats.values()):
        raise ValueError(f"{VOCABULARY_FILE}: expected format cf-planner-vocabulary with categories: name -> non-empty "
                         "list of texts")
    names = tuple(sorted(cats))
    return names, tuple(tuple(cats[n]) for n in names)


@functools.lru_cache(maxsize=1)
def _encoder():
    from conceptfusion.perception.featurizer import load_encoder  # optional heavy dependency (torch)

    return load_encoder(_TEXT_ENCODER)


@functools.lru_cache(maxsize=1)
def _vocabulary_embeddings() -> tuple[np.ndarray, np.ndarray]:
    """(T, D) unit embeddings of every vocabulary text and (T,) the category index of each."""
    _, texts = planner_vocabulary()
    flat = [t for group in texts for t in group]
    owner = np.concatenate([np.full(len(group), k) for k, group in enumerate(texts)])
    return _embed(tuple(flat)), owner


def _embed(texts: tuple[str, ...]) -> np.ndarray:
    e = np.asarray(_encoder().encode_text(list(texts)), np.float64)
    return e / np.maximum(np.linalg.norm(e, axis=1, keepdims=True), 1e-12)


@functools.lru_cache(maxsize=512)
def rank_categories(what: str) -> tuple[tuple[str, float], ...]:
    """Every vocabulary category with its similarity to ``what`` (the best of its texts), best first."""
    names, _ = planner_vocabulary()
    emb, owner = _vocabulary_embeddings()
    sims = emb @ _embed((what,))[0]
    best = np.full(len(names), -1.0)
    np.maximum.at(best, owner, sims)
    order = np.lexsort((np.arange(len(names)), -best))
    return tuple((names[i], float(best[i])) for i in order)


@functools.lru_cache(maxsize=64)
def guess_room(mark: str, rooms: tuple[str, ...]) -> tuple[str, float] | None:
    """The room name most like ``mark`` ("sofa" -> "living room"), from general word meaning only."""
    if not rooms:
        return None
    sims = _embed(tuple(rooms)) @ _embed((mark,))[0]
    k = int(np.argmax(sims))
    return rooms[k], float(sims[k])


class OfflinePlanner:
    """The default planner that ships (see the module doc for what it can and cannot do)."""

    name = "offline"

    def __init__(self, config: OfflinePlannerConfig = OfflinePlannerConfig()) -> None:
        self.config = config
        _vocabulary_embeddings()  # load the text tower and embed the vocabulary now, not in the first episode

    def propose(self, instruction: str, context: PlannerContext) -> Proposal:
        try:
            parsed = parse_instruction(instruction)
        except ValueError as err:
            return planner_failure(str(err))
        if context.has_map:
            return self._with_map(parsed, context)
        return self._without_map(parsed, context)

    # -- no map: general knowledge only -------------------------------------------------------

    def _ranked(self, what: str) -> tuple[tuple[str, float], ...]:
        return rank_categories(what) if what else ()

    def _without_map(self, p: ParsedInstruction, ctx: PlannerContext) -> Proposal:
        lines = []
        room = p.room
        if p.room_mark:
            guess = guess_room(p.room_mark, tuple(ctx.rooms))
            if guess is not None:
                room = guess[0]
                lines.append(f"no map: the room with the {p.room_mark} is probably the {room} ({guess[1]:.2f})")
        if p.relation:
            lines.append(f"no map: cannot check what is {p.relation} the {p.anchor}; searching for the {p.anchor}")
            goals = [GoalQuery(p.anchor, room)]
            goals += [GoalQuery(n, room) for n, _ in self._ranked(p.what)[: self.config.top_k - 1]]
            return Proposal(tuple(goals), "\n".join(lines))
        ranked = self._ranked(p.what)
        if not ranked:
            return planner_failure(f"nothing to look for in {p.what!r}: no object is named and there is no map to choose from",
                                   "\n".join(lines))
        top = ranked[: self.config.top_k]
        lines.append(f"'{p.what}' is most like " + ", ".join(f"{n} ({s:.2f})" for n, s in top))
        return Proposal(tuple(GoalQuery(n, room) for n, _ in top), "\n".join(lines))

    # -- with map context -----------------------------------------------------------------------

    def _with_map(self, p: ParsedInstruction, ctx: PlannerContext) -> Proposal:
        lines, questions = [], []
        objects = list(ctx.objects)
        lines.append(f"the map holds {len(objects)} objects" + (f" in {', '.join(ctx.rooms)}" if ctx.rooms else ""))
        room = p.room
        if p.room_mark:
            marks = [o for o in objects if o.name == p.room_mark and o.room]
            if not marks:
                return Proposal((), "\n".join(lines + [f"the {p.room_mark} is not in the map yet: explore"]))
            room = marks[0].room
            lines.append(f"the {p.room_mark} is in the {room}")
        if room is not None:
            objects = [o for o in objects if o.room == room]
            lines.append(f"{len(objects)} of them in the {room}")
        if p.relation:
            if not any(o.name == p.anchor for o in ctx.objects):
                return Proposal((), "\n".join(lines + [f"the {p.anchor} is not in the map yet: explore"]))
            fitting = []
            for o in objects:
                if o.name == p.anchor:
                    continue
                if p.relation == "near":
                    d = ctx.ask("howFar", o.name, p.anchor)
                    questions.append(f"howFar({o.name}, {p.anchor}) -> {'none' if d is None else f'{float(d):.2f} m'}")
                    ok = d is not None and float(d) <= self.config.near_m
                else:
                    fn = _COMPARATOR[p.relation]
                    ans = ctx.ask(fn, o.name, p.anchor)
                    questions.append(f"{fn}({o.name}, {p.anchor}) -> {ans}")
                    ok = bool(ans)
                if ok:
                    fitting.append(o)
            objects = fitting
            lines.append(f"{len(objects)} stand {p.relation} the {p.anchor}")
        if p.what:
            ranked = self._ranked(p.what)
            rank = {n: k for k, (n, _) in enumerate(ranked)}
            sim = dict(ranked)
            if ctx.exhausted:  # nothing left to explore: the best there is, among the best-ranked
                keep = [o for o in objects if rank.get(o.name, 10**9) < self.config.context_rank]
                lines.append("explored everything: taking the best-ranked object the map holds")
            else:
                keep = [o for o in objects if sim.get(o.name, -1.0) >= ranked[0][1] - self.config.fit_margin]
            objects = sorted(keep, key=lambda o: (rank[o.name], o.name))
            lines.append(f"fitting '{p.what}' (best: {ranked[0][0]} {ranked[0][1]:.2f}): "
                         + (", ".join(f"{o.name} {sim[o.name]:.2f}" for o in objects) or "none yet"))
        if not objects:
            return Proposal((), "\n".join(lines + ["nothing in the map fits yet: explore"]), questions=tuple(questions))
        goals = tuple(GoalQuery(o.name, room) for o in objects[: self.config.top_k])
        lines.append("go to " + ", ".join(str(g) for g in goals))
        return Proposal(goals, "\n".join(lines), questions=tuple(questions))
