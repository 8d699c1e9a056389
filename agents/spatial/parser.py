"""Natural-language spatial questions -> ONE comparator call, e.g. ``howFar(chair, sofa)``.

The public face of the parsers:

* :class:`SpatialQuestionParser` - the protocol: ``parse(question) -> ParseResult``.
* :class:`PatternParser` - the default, offline phrase-pattern parser
  (:mod:`agents.spatial.grammar`).
* :class:`SemanticParser` - the grammar as a fast path, then noun-phrase chunking and the
  relation classified by meaning with the MiniLM text tower (:mod:`agents.spatial.semantic`).
* :class:`LLMParser` - the paper's approach: its prompt sent to an OpenAI-compatible
  chat-completions server (:mod:`agents.spatial.llm`).
* :data:`PARSERS` / :func:`make_parser` - the lookup table of backends by name.
* :func:`calibrate_threshold` - the semantic parser's refusal threshold from development
  questions (:mod:`agents.spatial.calibration`).

Every result carries a ``confidence`` in [0, 1] (0 when it is not a call); see
:class:`ParseResult`.

The function names are the paper's eight (:data:`conceptfusion.spatial.comparators.COMPARATOR_NAMES`);
``conceptfusion.spatial.comparators.get_comparator(result.function)`` runs the call on two regions.
"""

from __future__ import annotations

from typing import Callable

from agents.spatial.calibration import calibrate_threshold, confidently_wrong_rate, score_questions
from agents.spatial.grammar import PatternParser, normalise_question, parse_question
from agents.spatial.llm import PAPER_PROMPT, LLMParser, LLMParserConfig
from agents.spatial.semantic import SemanticParser, SemanticParserConfig
from agents.spatial.signature import (
    SELF_REFERENCE,
    ParseResult,
    SpatialQuestionParser,
    cannot_parse,
    clean_noun_phrase,
    parse_signature,
    parsed,
)
from conceptfusion.names import unknown_name_error

__all__ = [
    "SpatialQuestionParser",
    "ParseResult",
    "PatternParser",
    "LLMParser",
    "SemanticParser",
    "SemanticParserConfig",
    "LLMParserConfig",
    "PAPER_PROMPT",
    "SELF_REFERENCE",
    "PARSERS",
    "make_parser",
    "parse_question",
    "parse_signature",
    "normalise_question",
    "clean_noun_phrase",
    "parsed",
    "cannot_parse",
    "calibrate_threshold",
    "confidently_wrong_rate",
    "score_questions",
]


def _make_llm(**kwargs) -> LLMParser:
    return LLMParser(LLMParserConfig(**kwargs))


def _make_pattern(**kwargs) -> PatternParser:
    if kwargs:
        raise TypeError(f"the pattern parser takes no options, got {sorted(kwargs)}")
    return PatternParser()


def _make_semantic(**kwargs) -> SemanticParser:
    return SemanticParser(SemanticParserConfig(**kwargs))


PARSERS: dict[str, Callable[..., SpatialQuestionParser]] = {
    "pattern": _make_pattern,
    "semantic": _make_semantic,
    "llm": _make_llm,
}
"""Parser backends by name; ``"semantic"`` takes the fields of :class:`SemanticParserConfig`,
``"llm"`` those of :class:`LLMParserConfig`."""


def make_parser(name: str = "pattern", **kwargs) -> SpatialQuestionParser:
    """Build the parser backend ``name`` (``"pattern"``, ``"semantic"`` or ``"llm"``) with its options.

    Raises ``ValueError`` naming the nearest valid names for an unknown ``name``.
    """
    if not isinstance(name, str):
        raise TypeError(f"name: expected a str, got {type(name).__name__}")
    factory = PARSERS.get(name)
    if factory is None:
        raise unknown_name_error("spatial parser", name, PARSERS, n=2, listing=f"valid: {', '.join(PARSERS)}")
    return factory(**kwargs)
