"""The semantic parser's refusal threshold, derived from development questions by a fixed rule.

**The rule** (written down before any confidence of any question was
computed): the threshold is the smallest ``t`` on the grid ``k / 1000`` (``k = 0 .. 1000``) at
which, over all rows of the development question sets, the rows answered with confidence
``>= t`` and a signature other than the expected one (answers to out-of-scope rows, expected
``None``, included) are at most :data:`MAX_CONFIDENTLY_WRONG_RATE` (0.25%, half the 0.5% target)
of the rows. Raising ``t`` only removes answers, so the rate never rises with ``t`` and "the
smallest" is well defined; the grid keeps the value short and unmoved by the last bits of
floating-point noise in the text tower.

The development sets are ``tests/agents/data/spatial_questions.jsonl``,
``spatial_questions_fresh1.jsonl`` and ``spatial_questions_fresh2.jsonl``; the sealed
``spatial_questions_fresh3.jsonl`` is never used for it. The rows are scored with the threshold
off (``SemanticParserConfig(min_confidence=0.0)``), and the derived value is the default of
:attr:`agents.spatial.semantic.SemanticParserConfig.min_confidence`;
``tests/agents/test_spatial_parser.py`` recomputes it from the files and checks equality.
"""

from __future__ import annotations

from typing import Iterable, Sequence

from agents.spatial.signature import ParseResult, SpatialQuestionParser

__all__ = [
    "MAX_CONFIDENTLY_WRONG_RATE",
    "GRID_STEPS",
    "DEVELOPMENT_SETS",
    "score_questions",
    "confidently_wrong_rate",
    "calibrate_threshold",
]

MAX_CONFIDENTLY_WRONG_RATE = 0.0025
"""Most confidently-wrong answers allowed on the development rows, as a fraction of the rows."""
GRID_STEPS = 1000
"""Thresholds tried: ``k / GRID_STEPS`` for ``k = 0 .. GRID_STEPS``."""
DEVELOPMENT_SETS = ("spatial_questions.jsonl", "spatial_questions_fresh1.jsonl", "spatial_questions_fresh2.jsonl")
"""File names (in ``tests/agents/data``) of the development question sets the threshold comes from."""

Scored = tuple[ParseResult, "str | None"]
"""A parser's result on one question and the expected signature (``None``: it should refuse)."""


def score_questions(parser: SpatialQuestionParser, rows: Iterable[dict]) -> list[Scored]:
    """``(parser.parse(row["question"]), row["expected"])`` for each question row."""
    out = []
    for row in rows:
        if not isinstance(row, dict) or not isinstance(row.get("question"), str) or "expected" not in row:
            raise ValueError(f"rows: expected dicts with 'question' (str) and 'expected', got {row!r}")
        out.append((parser.parse(row["question"]), row["expected"]))
    return out


def _confidently_wrong(result: ParseResult, expected: str | None, threshold: float) -> bool:
    return result.ok and result.confidence >= threshold and result.signature != expected


def confidently_wrong_rate(scored: Sequence[Scored], threshold: float = 0.0) -> float:
    """Fraction of ``scored`` answered with confidence ``>= threshold`` and a wrong signature."""
    if not scored:
        raise ValueError("scored: expected at least one row")
    return sum(_confidently_wrong(r, e, threshold) for r, e in scored) / len(scored)


def calibrate_threshold(scored: Sequence[Scored], max_rate: float = MAX_CONFIDENTLY_WRONG_RATE,
                        steps: int = GRID_STEPS) -> float:
    """The smallest grid threshold whose confidently-wrong rate on ``scored`` is ``<= max_rate``.

    ``scored``: results of a parser with its own threshold off, with the expected signatures
    (see the module doc for the rule). Raises ``ValueError`` when no threshold up to 1.0 meets
    ``max_rate`` (wrong answers at confidence 1.0 are more than it allows).
    """
    if not 0.0 <= max_rate <= 1.0:
        raise ValueError(f"max_rate: expected a fraction in [0, 1], got {max_rate!r}")
    if not isinstance(steps, int) or steps < 1:
        raise ValueError(f"steps: expected a positive int, got {steps!r}")
    wrong = sorted(r.confidence for r, e in scored if _confidently_wrong(r, e, 0.0))
    allowed = int(max_rate * len(scored) + 1e-9)  # at most this many wrong answers may remain
    for k in range(steps + 1):
        t = k / steps
        remaining = sum(c >= t for c in wrong)
        if remaining <= allowed:
            return t
    raise ValueError(
        f"no threshold up to 1.0 keeps confidently-wrong answers within {max_rate:.2%} of {len(scored)} rows: "
        f"{sum(c >= 1.0 for c in wrong)} wrong answers have confidence 1.0 (allowed {allowed})")
