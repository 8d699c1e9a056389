"""Offline spatial-question parser: normalisation, phrase patterns, noun-phrase clean-up.

How a question is read:

1. **Normalise**: lower case, contractions expanded ("what's" -> "what is"), end punctuation
   dropped, commas and colons kept as separate ``,`` tokens.
2. **Strip lead-ins** such as "can you tell me", "I want to know", "please", "check whether".
3. **Match** an ordered list of patterns, one family per comparator, most specific first
   (left/right before "on", "fit in" before "in"). A pattern names where the two objects sit
   and whether they are swapped ("is A smaller than B" -> ``isBigger(B, A)``; "does B contain
   A" -> ``isContained(A, B)``).
4. **Clean the two phrases**: auxiliaries, "there", articles and determiners are removed from
   the front; copulas, posture verbs and adverbs from the end ("the cat sitting" -> "cat");
   adjectives stay. A phrase that is empty, a pronoun, or names two things ("the sofa and the
   table") rejects that pattern.

Patterns of the bare form "A <preposition> B" (on, in, under, left of, near) also need a verb:
A must start with an auxiliary ("is the mug ...") or end with a copula or posture verb ("the
mug is ..."), so commands like "turn on the lights" are not read as relations.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from agents.spatial.signature import (
    ParseResult,
    cannot_parse,
    clean_noun_phrase,
    noun_phrase_problem,
    parsed,
)

__all__ = ["PatternParser", "parse_question", "normalise_question", "CONTRACTIONS"]

# ---------------------------------------------------------------------------------------------
# Normalisation
# ---------------------------------------------------------------------------------------------

CONTRACTIONS = (
    (r"\bcan't\b", "can not"),
    (r"\bwon't\b", "will not"),
    (r"\b(\w+)n't\b", r"\1 not"),
    (r"\b(what|where|how|who|which|that|it|there|here)'s\b", r"\1 is"),
    (r"\bi'm\b", "i am"),
    (r"\b(i|you|we|they)'d\b", r"\1 would"),
    (r"\b(i|you|we|they)'re\b", r"\1 are"),
    (r"\b(i|you|we|they)'ve\b", r"\1 have"),
)

_LEAD_INS = re.compile(
    r"^(?:"
    r"(?:hey|hi|ok|okay|so|robot|excuse me|quick question|question)\b ?,? ?"
    r"|please "
    r"|(?:roughly|approximately|about|exactly|just|honestly) "
    r"|(?:(?:can|could|would|will) you (?:please )?)?"
    r"(?:tell me|check|find out|figure out|estimate|measure|determine|let me know|verify|confirm|"
    r"compute|calculate|work out|say|guess|show me|find|give me|get)(?: for me)?\b ?,? ?"
    r"|(?:do|does) (?:you|anyone|anybody) (?:know|think)\b ?"
    r"|(?:i|we) (?:would like|want|need|wish|wanted|am trying|are trying) to (?:know|find out|check|see)\b ?"
    r"|(?:i|we) (?:am |are )?wonder(?:ing)?\b ?"
    r"|would you say\b ?"
    r"|(?:in your opinion|do you think|tell me)\b ?,? ?"
    r"|(?:whether|if)\b ?"
    r")"
)
_TRAILERS = re.compile(
    r"(?:(?: ,)? (?:please|for me|or not|thanks|thank you|roughly|approximately|more or less|precisely)"
    r"| , (?:right|correct|yes or no|true or false|exactly|about))$"
)


def normalise_question(question: str) -> str:
    """Lower-cased, contraction-free, lead-in-free form of ``question`` (see the module doc)."""
    text = question.lower().replace("\u2019", "'").replace("\u2018", "'")
    text = text.replace('"', " ").replace("`", " ")
    for pattern, repl in CONTRACTIONS:
        text = re.sub(pattern, repl, text)
    text = re.sub(r"[;:]", ",", text)
    text = re.sub(r"\s*,\s*", " , ", text)
    text = re.sub(r"[?!.\s]+$", "", text)
    text = re.sub(r"\s+", " ", text).strip(" ,")
    while True:
        shorter = _LEAD_INS.sub("", text, count=1).strip(" ,")
        shorter = _TRAILERS.sub("", shorter).strip(" ,")
        if shorter == text or not shorter:
            return shorter or text
        text = shorter


# ---------------------------------------------------------------------------------------------
# Noun-phrase edges
# ---------------------------------------------------------------------------------------------

_AUX = {
    "is", "are", "was", "were", "does", "do", "did", "will", "would", "can", "could", "should",
    "may", "might", "has", "have", "had", "not",
}
_LEADING_NOISE = _AUX | {"there", "you", "i", "we", "see", "find", "spot", "notice", "also"}
_COPULAS = {"is", "are", "was", "were", "be", "been", "being", "not"}
_POSTURE = {
    # participles and base forms of "where/how it is placed" verbs; -ing forms are generic
    "located", "situated", "positioned", "placed", "stored", "kept", "stacked", "perched",
    "draped", "tucked", "hidden", "stuck", "hung", "sat", "parked", "mounted", "contained",
    "packed", "left", "lying", "found", "piled", "laid", "lain", "enclosed", "sits", "stands",
    "lies", "rests", "hangs", "leans", "goes", "belongs", "appears", "seems", "stays", "lives",
    "sleeps", "fell", "fallen", "asleep", "awake", "curled", "sprawled", "seated", "balanced",
    "leaning", "up",
}
# Base forms double as nouns ("umbrella stand", "TV stand"): dropped only after do-support or a
# modal ("does the bookshelf stand ...", "would the box go ...").
_BASE_VERBS = {
    "sit", "stand", "lie", "rest", "hang", "lean", "go", "belong", "appear", "seem", "stay",
    "live", "sleep", "fall", "be",
}
_DO_SUPPORT = {"does", "do", "did", "will", "would", "could", "should", "may", "might", "can"}
_ADVERBS = {
    "currently", "still", "actually", "really", "directly", "right", "just", "exactly",
    "somewhere", "completely", "fully", "entirely", "already", "now", "also", "safely",
    "neatly", "probably", "maybe", "partly", "partially", "away", "further", "farther", "apart",
}
_ING_NOUNS = {
    "painting", "ceiling", "building", "clothing", "railing", "bedding", "drawing", "wedding",
    "stuffing", "icing", "frosting", "seating", "lighting", "dressing", "pudding", "stocking",
    "carving", "ring", "string", "king", "wing", "spring", "swing", "sling", "thing", "sibling",
    "duckling", "dumpling", "awning", "tubing", "padding", "filling", "booking", "charging",
    "heating", "plumbing", "shelving", "flooring", "siding", "fencing", "roofing", "decking",
}
_MODALS = {"will", "would", "could", "should", "may", "might", "does", "do", "did", "has", "have"}  # not "can": "trash can"
_TAIL_NOISE = _COPULAS | _MODALS | _POSTURE | _ADVERBS
_END_NOISE = _COPULAS | _MODALS | _ADVERBS


def _is_verbish(word: str, at_end: bool, do_support: bool) -> bool:
    if at_end:
        return word in _END_NOISE
    if word in _TAIL_NOISE or (do_support and word in _BASE_VERBS):
        return True
    return word.endswith("ing") and len(word) > 5 and word not in _ING_NOUNS


def _trim_edges(raw: str, *, at_end: bool) -> tuple[str, bool]:
    """Strip leading auxiliaries and trailing verbs/adverbs; report whether a verb was seen.

    A phrase that ends the question (``at_end``) only loses copulas, modals and adverbs at its
    end ("how far apart the bed and the sofa are"): its last word is otherwise a noun
    ("umbrella stand", "knife set").
    """
    words = [w for w in raw.split() if w]
    saw_verb = False
    do_support = bool(words) and words[0] in _DO_SUPPORT
    while len(words) > 1 and words[0] in _LEADING_NOISE:
        saw_verb |= words[0] in _AUX
        words = words[1:]
    while len(words) > 1 and _is_verbish(words[-1], at_end, do_support):
        saw_verb |= words[-1] not in _ADVERBS
        words = words[:-1]
    return " ".join(words), saw_verb


_VIEWPOINT = re.compile(
    r"(?: ,)? (?:(?:as )?(?:seen |viewed |looking |when viewed |when looking )?from "
    r"(?:my|your|our|the camera's|the robot's|this|the) (?:point of view|perspective|viewpoint|"
    r"view|vantage point|angle|side|position|pov)"
    r"|(?:as )?(?:seen |viewed |looking )?from (?:where (?:i|we|you) (?:am|are|is|stand|sit)"
    r"(?: standing| sitting)?|here|the door(?:way)?|the entrance)"
    r"|when (?:i|you|we) (?:face|look at) (?:it|them))$"
)
_OBJECT_TAIL = re.compile(r"(?: ,)? (?:right now|at the moment|currently|at present|now|today|or not)$")


# ---------------------------------------------------------------------------------------------
# Patterns
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Pattern:
    function: str
    regex: re.Pattern
    needs_verb: bool = False
    """Bare "A <preposition> B" form: A must carry an auxiliary or a verb."""


def _p(function: str, pattern: str, *, needs_verb: bool = False) -> _Pattern:
    return _Pattern(function, re.compile("^" + pattern + "$"), needs_verb)


_A, _B = r"(?P<a>.+?)", r"(?P<b>.+?)"
_SIDE_TAIL = r"(?:[- ]hand)?(?: side)?"
_UNITS = r"(?:meters|metres|meter|metre|m|feet|foot|ft|centimeters|centimetres|cm|inches|yards|steps|paces|kilometers|km|miles)"
_PUT = r"(?:put|place|fit|store|stuff|squeeze|pack|get|slide|stick|keep|carry|set)"
_INTO = r"(?:into|inside of|inside|in|within)"
_BIG = r"(?:bigger|larger|greater|huger|bulkier|more voluminous|more massive)"
_SMALL = r"(?:smaller|tinier|littler|more compact|less bulky)"
_SIZE_TAIL = r"(?: in (?:size|volume|overall size))?"

_PATTERNS: tuple[_Pattern, ...] = (
    # --- left / right ---------------------------------------------------------------------
    _p("side", _A + r" (?:to|on|at|towards|toward) (?:the )?(?P<side>left|right)" + _SIDE_TAIL + r" of " + _B, needs_verb=True),
    _p("side", _A + r" (?:more )?(?P<side>left|right)(?:wards?)? of " + _B, needs_verb=True),
    _p("side", _A + r" (?:to|on|at) " + _B + r"'s (?P<side>left|right)" + _SIDE_TAIL, needs_verb=True),
    # --- fitting --------------------------------------------------------------------------
    _p("canFitInside", _A + r"(?: (?:small|little|short|thin|narrow|compact|tiny) enough)?(?: to)?(?: be able to)?"
       r" (?:fit|fits|squeeze|slide|go|goes) " + _INTO + " " + _B),
    _p("canFitInside", r"(?:can|could|may|should|will|would|might) (?:i|we|you|someone|the robot) (?:possibly )?" + _PUT
       + " " + _A + " " + _INTO + " " + _B),
    _p("canFitInside", r"(?:i|we) (?:want|would like|need|am going|are going|plan|intend|wish|try|am trying|are trying)"
       r" to (?:grab (?P<grab>.+?) and )?" + _PUT + " " + _A + " " + _INTO + " " + _B),
    _p("canFitInside", r"(?:is|would it be|will it be) (?:it )?possible to " + _PUT + " " + _A + " " + _INTO + " " + _B),
    _p("canFitInside", _B + r" (?:big|large|roomy|spacious|deep|wide|tall|long|high) enough"
       r" (?:for|to (?:hold|fit|contain|take|carry|store|accommodate|put)) " + _A),
    _p("canFitInside", r"(?:is|are) there (?:enough |any |sufficient )?(?:room|space) for " + _A + " " + _INTO + " " + _B),
    _p("canFitInside", r"(?:is|are) there (?:enough |any |sufficient )?(?:room|space) " + _INTO + " " + _B + r" for " + _A),
    _p("canFitInside", _B + r" (?:accommodate|accommodates|have (?:enough )?(?:room|space) for|has (?:enough )?(?:room|space) for) " + _A),
    # --- size -----------------------------------------------------------------------------
    _p("isBigger", _A + " " + _BIG + _SIZE_TAIL + r" than " + _B),
    _p("isBigger", _B + " " + _SMALL + _SIZE_TAIL + r" than " + _A),
    _p("isBigger", _A + r" (?:take|takes|take up|takes up|occupy|occupies) more (?:space|room|volume) than " + _B),
    _p("isBigger", _B + r" (?:take|takes|take up|takes up|occupy|occupies) less (?:space|room|volume) than " + _A),
    _p("isBigger", _A + r" (?:has|have) (?:a )?(?:bigger|larger|greater) (?:size|volume|footprint) than " + _B),
    _p("isBigger", r"which (?:one |object |item |thing |of the two )?(?:is|would be) " + _BIG + _SIZE_TAIL
       + r"(?: ,)? (?:between )?" + _A + r"(?: ,)? (?:or|and) " + _B),
    _p("isBigger", r"which (?:one |object |item |thing |of the two )?(?:is|would be) " + _SMALL + _SIZE_TAIL
       + r"(?: ,)? (?:between )?" + _B + r"(?: ,)? (?:or|and) " + _A),
    _p("isBigger", _A + r" or " + _B + r"(?: ,)? which (?:one )?is " + _BIG),
    _p("isBigger", _B + r" or " + _A + r"(?: ,)? which (?:one )?is " + _SMALL),
    # --- distance -------------------------------------------------------------------------
    _p("howFar", r"(?:how (?:far|long|many " + _UNITS + r")|what is the distance)(?: away)?(?: is it| it is| would it be|"
       r" is the (?:walk|trip|way|path|route|distance|drive)| is)?"
       r"(?: (?:do|would|will|did|must|should) (?:i|we|you|one|the robot) (?:have to |need to )?(?:go|walk|travel|drive|move))?"
       r" from " + _A + r" to " + _B),
    _p("howFar", r"how (?:far|close|near)(?: away)? from " + _B + r" (?:is|are) " + _A),
    _p("howFar", r"how (?:far|close|near)(?: away)?(?: apart)? (?:is |are )?" + _A + r" and " + _B),
    _p("howFar", r"how (?:far|close|near|distant)(?: away)? " + _A + r" (?:from|to) " + _B),
    _p("howFar", r"(?:what is |give me |get )?(?:the |a )?(?:approximate |rough |exact |current |straight line |"
       r"straight-line |euclidean )?(?:distance|gap|separation|spacing) (?:between|separating|that separates) "
       + _A + r" (?:and|from) " + _B),
    _p("howFar", r"(?:what is |give me |get )?(?:the |a )?(?:approximate |rough |exact )?distance from " + _A + r" to " + _B),
    _p("howFar", r"how much (?:space|room|distance|of a gap) (?:is there )?between " + _A + r" and " + _B),
    _p("howFar", r"how many " + _UNITS + r" (?:separate|lie between|are between|are there between|is it between|"
       r"between|there are between|apart are) " + _A + r" and " + _B),
    _p("howFar", r"how many " + _UNITS + r" (?:apart |away )?(?:is|are) " + _A + r" (?:from|to) " + _B),
    _p("howFar", r"where is (?:the )?(?:closest|nearest) " + _A + r" (?:from|to) " + _B),
    # --- under / on top / inside (bare prepositions) ----------------------------------------
    _p("under", _A + r" (?:under|underneath|beneath|below|down under|under neath) " + _B, needs_verb=True),
    _p("onTopOf", r"(?:does|do|did) " + _B + r" (?:have|has) " + _A
       + r" (?:(?:sitting |lying |resting |placed |standing )?on (?:top of )?(?:it|them)|on top)"),
    _p("isContained", r"(?:does|do|did) " + _B + r" (?:have|has) " + _A + r" (?:in|inside|within) (?:it|them|there)"),
    _p("onTopOf", _A + r" (?:on top of|on the top of|atop|upon|onto|on|over|above) " + _B, needs_verb=True),
    _p("isContained", _B + r" (?:contain|contains|hold|holds|include|includes|have inside|has inside) " + _A),
    _p("isContained", _A + r" (?:inside of|inside|within|into|in) " + _B, needs_verb=True),
    _p("howFar", _A + r" (?:near|close to|close by|nearby|next to|far from|far away from|a long way from|"
       r"distant from|a long distance from) " + _B, needs_verb=True),
)


def _first_problem(problems: list[str]) -> str:
    return problems[0] if problems else "no supported spatial relation found"


def parse_question(question: str) -> ParseResult:
    """Parse ``question`` into one comparator call with the offline patterns.

    Never raises for text it does not understand: the :class:`ParseResult` then carries the
    reason (empty question, no relation, one object, more than two objects, a pronoun).
    """
    if not isinstance(question, str):
        raise TypeError(f"question: expected a str, got {type(question).__name__}")
    if not question.strip():
        return cannot_parse("empty question")
    text = normalise_question(question)
    problems: list[str] = []
    for pattern in _PATTERNS:
        match = pattern.regex.match(text)
        if match is None:
            continue
        raw_a, raw_b = match.group("a"), match.group("b")
        function = pattern.function
        if function == "side":
            function = "isToTheLeft" if match.group("side") == "left" else "isToTheRight"
            raw_b = _VIEWPOINT.sub("", raw_b)
        raw_b = _OBJECT_TAIL.sub("", raw_b)
        grabbed = match.groupdict().get("grab")
        if grabbed and noun_phrase_problem(clean_noun_phrase(raw_a)):
            raw_a = grabbed  # "grab a can of soda and put this into a bag"
        a_first = match.start("a") < match.start("b")
        a_text, a_verb = _trim_edges(raw_a, at_end=not a_first and match.end("a") == len(text))
        b_text, b_verb = _trim_edges(raw_b, at_end=a_first and match.end("b") == len(text))
        subject_has_verb = a_verb if a_first else b_verb
        if pattern.needs_verb and not subject_has_verb:
            problems.append(f"{function}: no verb before {raw_a!r}; not a question about a relation")
            continue
        a, b = clean_noun_phrase(a_text), clean_noun_phrase(b_text)
        bad = next(
            (f"{function}: {which} {p}" for which, p in (("object1", noun_phrase_problem(a)), ("object2", noun_phrase_problem(b))) if p),
            None,
        )
        if bad is not None:
            problems.append(bad)
            continue
        if a == b:
            problems.append(f"{function}: both arguments are {a!r}; need two different objects")
            continue
        return parsed(function, a, b)
    return cannot_parse(_first_problem(problems))


@dataclass(frozen=True)
class PatternParser:
    """The offline :class:`~agents.spatial.signature.SpatialQuestionParser` (no model, no network).

    A call carries confidence 1.0: the patterns have no graded doubt (the semantic parser's fast
    path adds one, :mod:`agents.spatial.semantic`).
    """

    def parse(self, question: str) -> ParseResult:
        """See :func:`parse_question`."""
        return parse_question(question)
