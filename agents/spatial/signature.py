"""What a spatial-question parser returns, and the checks shared by every parser backend.

A parse is ONE comparator call: a function name among the paper's eight 3DSCs
(``conceptfusion.spatial.comparators.COMPARATOR_NAMES``) and two object noun phrases, e.g.
``howFar(chair, sofa)``, with the parser's confidence in it; or a "cannot parse" result with a
reason (confidence 0).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Protocol

from conceptfusion.spatial.comparators import COMPARATOR_NAMES

__all__ = [
    "ParseResult",
    "SpatialQuestionParser",
    "parsed",
    "cannot_parse",
    "clean_noun_phrase",
    "noun_phrase_problem",
    "parse_signature",
    "SELF_REFERENCE",
]

SELF_REFERENCE = "my location"
"""The object name used for the asker themself ("me", "here", "where I am"), as in the paper."""

_CANONICAL = {name.lower(): name for name in COMPARATOR_NAMES}


@dataclass(frozen=True)
class ParseResult:
    """One parsed question: a comparator call, or the reason no call could be made."""

    function: str | None
    """One of the paper's eight comparator names, or ``None`` when the question was not parsed."""
    arguments: tuple[str, str] | None
    """The two object noun phrases (lower case, no articles), or ``None``."""
    reason: str = ""
    """Why the question could not be parsed (empty on success, never empty on failure)."""
    confidence: float | None = None
    """How sure the parser is of the call, in [0, 1]: in (0, 1] for a call, 0.0 for a failure.
    Left out (``None``), it becomes 1.0 for a call and 0.0 for a failure. What it means per
    backend: 1.0 for a call the grammar reads outright or a reply that names the call (pattern,
    LLM); for the semantic parser's relation classes, the probability of the chosen class
    (:mod:`agents.spatial.semantic`)."""

    def __post_init__(self) -> None:
        if self.confidence is None:
            object.__setattr__(self, "confidence", 0.0 if self.function is None else 1.0)
        if isinstance(self.confidence, bool) or not isinstance(self.confidence, (int, float)):
            raise TypeError(f"ParseResult: confidence must be a number, got {type(self.confidence).__name__}")
        if math.isnan(self.confidence) or not 0.0 <= self.confidence <= 1.0:
            raise ValueError(f"ParseResult: confidence must be in [0, 1], got {self.confidence!r}")
        object.__setattr__(self, "confidence", float(self.confidence))
        if self.function is None and self.confidence != 0.0:
            raise ValueError(f"ParseResult: a failed parse has confidence 0, got {self.confidence!r}")
        if self.function is not None and self.confidence == 0.0:
            raise ValueError("ParseResult: a parsed call needs a confidence above 0")
        if (self.function is None) != (self.arguments is None):
            raise ValueError("ParseResult: function and arguments must both be set or both be None")
        if self.function is not None and self.function not in COMPARATOR_NAMES:
            raise ValueError(f"ParseResult: unknown function {self.function!r}; expected one of {COMPARATOR_NAMES}")
        if self.arguments is not None and (
            len(self.arguments) != 2 or not all(isinstance(a, str) and a for a in self.arguments)
        ):
            raise ValueError(f"ParseResult: expected two non-empty argument strings, got {self.arguments!r}")
        if self.function is None and not self.reason:
            raise ValueError("ParseResult: a failed parse needs a reason")

    @property
    def ok(self) -> bool:
        """Whether the question was parsed into a comparator call."""
        return self.function is not None

    @property
    def signature(self) -> str | None:
        """The call as the paper writes it, e.g. ``"howFar(chair, sofa)"``; ``None`` if not parsed."""
        if self.function is None or self.arguments is None:
            return None
        return f"{self.function}({self.arguments[0]}, {self.arguments[1]})"


class SpatialQuestionParser(Protocol):
    """Turns a natural-language question into one comparator call."""

    def parse(self, question: str) -> ParseResult:
        """Parse ``question``; never raises for a question it cannot handle (returns a reason)."""
        ...


def parsed(function: str, object1: str, object2: str, confidence: float = 1.0) -> ParseResult:
    """A successful :class:`ParseResult` (``confidence`` in (0, 1], 1.0 unless said)."""
    return ParseResult(function=function, arguments=(object1, object2), confidence=confidence)


def cannot_parse(reason: str) -> ParseResult:
    """A failed :class:`ParseResult` carrying ``reason`` (confidence 0)."""
    return ParseResult(function=None, arguments=None, reason=reason, confidence=0.0)


# ---------------------------------------------------------------------------------------------
# Noun phrases
# ---------------------------------------------------------------------------------------------

_DETERMINERS = {
    "the", "a", "an", "this", "that", "these", "those", "my", "your", "our", "their", "his",
    "her", "its", "some", "any", "each", "every", "one", "of",
}
_SELF = re.compile(
    r"^(?:me|myself|us|here|my (?:current )?(?:location|position|spot)|where i (?:am|stand)(?: standing| now)?|"
    r"where we are|the place where i am)$"
)
_PRONOUNS = {
    "it", "they", "them", "this", "that", "these", "those", "something", "anything",
    "everything", "nothing", "one", "ones", "what", "which", "where", "who", "whom", "there",
    "thing", "things", "stuff", "object", "objects", "he", "she", "him", "her", "i", "you", "we",
}
_DIRECTIONS = {"left", "right", "top", "bottom", "front", "back", "side", "middle", "center", "centre", "up", "down"}
# Prepositions and conjunctions that mean the phrase names a second object or a relation.
_SPLITTERS = {
    "and", "or", "on", "in", "inside", "under", "underneath", "beneath", "below", "above",
    "over", "near", "next", "beside", "besides", "behind", "between", "from", "to", "with",
    "into", "onto", "within", "atop", "upon", "than", "by", "at", "across", "around", "against",
    "toward", "towards", "fit", "fits",
}
_RELATIONAL_HEAD = re.compile(r"^(?:front|back|middle|center|centre|corner|side|edge|top|bottom|rear) of\b")


def clean_noun_phrase(text: str) -> str:
    """Lower-case ``text``, strip outer punctuation and leading determiners; map self-references.

    Adjectives stay: ``"The red mug."`` -> ``"red mug"``; ``"me"`` / ``"my location"`` ->
    :data:`SELF_REFERENCE`. Does not judge the result: see :func:`noun_phrase_problem`.
    """
    if not isinstance(text, str):
        raise TypeError(f"text: expected a str, got {type(text).__name__}")
    phrase = re.sub(r"\s+", " ", text.lower().replace("\u2019", "'")).strip(" \t\"'`.,;:!?()[]")
    if _SELF.match(phrase):
        return SELF_REFERENCE
    words = phrase.split()
    while len(words) > 1 and words[0] in _DETERMINERS:
        words = words[1:]
    phrase = " ".join(words)
    return SELF_REFERENCE if _SELF.match(phrase) else phrase


def noun_phrase_problem(phrase: str) -> str | None:
    """Why a cleaned phrase does not name exactly one object, or ``None`` when it does."""
    if not phrase:
        return "names no object"
    if phrase == SELF_REFERENCE:
        return None
    words = phrase.split()
    if len(words) == 1 and words[0] in _PRONOUNS | _DETERMINERS:
        return f"{phrase!r} is a pronoun, not an object name"
    if all(w in _DIRECTIONS for w in words):
        return f"{phrase!r} is a direction, not an object"
    if "," in phrase or any(w in ("and", "or") for w in words):
        return f"{phrase!r} names more than one object"
    if any(w in _SPLITTERS for w in words):
        return f"{phrase!r} names more than one object or an unsupported relation"
    if _RELATIONAL_HEAD.match(phrase):
        return f"{phrase!r} is an unsupported relation (not one of the eight comparators)"
    if len(words) > 6:
        return f"{phrase!r} is too long to be one object name"
    return None


# ---------------------------------------------------------------------------------------------
# Signatures written as text ("howFar(chair, sofa)")
# ---------------------------------------------------------------------------------------------

_CALL = re.compile(r"([A-Za-z_][A-Za-z0-9_]*)\s*\(([^()]*)\)")


def parse_signature(text: str) -> ParseResult:
    """Parse a call written as text, e.g. an LLM's ``"Response: howFar(chair, sofa)"``.

    The first ``name(...)`` in ``text`` is taken. The name must be one of the eight (case is
    forgiven: ``howfar`` -> ``howFar``) and it must have exactly two arguments that each name
    one object (quotes and articles are stripped). Anything else gives a cannot-parse result.
    A call found this way has confidence 1.0: the text names it outright, and the text carries
    no measure of doubt to read.
    """
    if not isinstance(text, str):
        raise TypeError(f"text: expected a str, got {type(text).__name__}")
    match = _CALL.search(text)
    if match is None:
        snippet = text.strip()[:80]
        return cannot_parse(f"no function call found in {snippet!r}")
    name, inside = match.group(1), match.group(2)
    canonical = _CANONICAL.get(name.lower())
    if canonical is None:
        return cannot_parse(f"unknown function {name!r} (expected one of {', '.join(COMPARATOR_NAMES)})")
    args = [a for a in (part.strip() for part in inside.split(","))]
    if len(args) != 2:
        return cannot_parse(f"{canonical} needs exactly two arguments, got {len(args)} in {match.group(0)!r}")
    cleaned = [clean_noun_phrase(a) for a in args]
    for position, phrase in zip(("first", "second"), cleaned):
        problem = noun_phrase_problem(phrase)
        if problem is not None:
            return cannot_parse(f"{canonical}: {position} argument {problem}")
    return parsed(canonical, cleaned[0], cleaned[1])
