"""Question templates of the ``spatial`` suite: many phrasings per comparator, from a data file.

:file:`spatial_templates.json` holds, per comparator name (the eight of
:data:`conceptfusion.spatial.comparators.COMPARATOR_NAMES`), a list of templates: an ``id``
(unique over the file), a ``text`` with the slots ``{a}`` and ``{b}`` (each at least once, no
other braces), asking ``comparator(a, b)`` whatever order the names appear in, and ``fresh``:
whether the phrasing is unlike the parser's development questions and exemplars (the suite
reports accuracy on the fresh share apart). :func:`load_templates` checks all of it.

:func:`template_pattern` is how a phrasing is looked for in a set of questions: lower case,
words only, each slot (with a determiner before it) matching one or more words.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path

from conceptfusion.errors import HarnessError
from conceptfusion.names import lookup
from conceptfusion.spatial.comparators import COMPARATOR_NAMES

__all__ = ["TEMPLATES_PATH", "MIN_TEMPLATES", "SpatialTemplate", "load_templates", "template_pattern", "normalise_text"]

TEMPLATES_PATH = Path(__file__).with_name("spatial_templates.json")
"""The shipped template file."""

MIN_TEMPLATES = 10
"""Least number of templates per comparator."""

_SLOTS = ("{a}", "{b}")
_DETERMINERS = frozenset({"the", "a", "an"})


@dataclass(frozen=True)
class SpatialTemplate:
    """One phrasing of one comparator."""

    id: str
    comparator: str
    """The comparator the question asks, called as ``comparator(a, b)``."""
    text: str
    """The question with ``{a}`` and ``{b}`` slots."""
    fresh: bool
    """Phrased unlike the parser's development questions and exemplars."""

    def fill(self, a: str, b: str) -> str:
        """The question about objects ``a`` and ``b``."""
        return self.text.replace("{a}", a).replace("{b}", b)


def normalise_text(text: str) -> str:
    """Lower case, words (letters, digits, apostrophes; a possessive ``'s`` split off)
    separated by single spaces."""
    return " ".join(re.findall(r"[a-z0-9']+|[{][ab][}]", text.lower().replace("'s", " 's")))


def template_pattern(template: SpatialTemplate | str) -> re.Pattern:
    """A regex that finds the template's phrasing in :func:`normalise_text` output.

    Each slot, with a determiner right before it, matches one or more words (``"the red mug"``,
    or ``"x"`` in an exemplar ``"is X on Y"``); the other words must appear as written.
    """
    text = template.text if isinstance(template, SpatialTemplate) else str(template)
    words = normalise_text(text).split()
    out: list[str] = []
    for k, w in enumerate(words):
        if w in _DETERMINERS and k + 1 < len(words) and words[k + 1] in _SLOTS:
            continue
        if w in _SLOTS:
            out.append(r"[a-z0-9']+(?: [a-z0-9']+)*?")
        else:
            out.append(re.escape(w))
    return re.compile(r"(?<![a-z0-9'])" + " ".join(out) + r"(?![a-z0-9'])")


def _fail(path: Path, what: str) -> HarnessError:
    return HarnessError(f"spatial templates {path}: {what}")


def _load(path: str) -> dict[str, tuple[SpatialTemplate, ...]]:
    p = Path(path)
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise _fail(p, "no such file") from None
    except json.JSONDecodeError as exc:
        raise _fail(p, f"not valid JSON ({exc})") from None
    if not isinstance(data, dict) or not isinstance(data.get("templates"), dict):
        raise _fail(p, f"expected an object with a 'templates' object (comparator -> list), got {type(data).__name__}"
                       + ("" if not isinstance(data, dict) else f" with keys {sorted(data)}"))
    out: dict[str, tuple[SpatialTemplate, ...]] = {}
    seen: dict[str, str] = {}
    for name, items in data["templates"].items():
        comparator = lookup({c: c for c in COMPARATOR_NAMES}, name, "comparator")
        if not isinstance(items, list) or len(items) < MIN_TEMPLATES:
            got = f"{len(items)}" if isinstance(items, list) else type(items).__name__
            raise _fail(p, f"{comparator}: expected a list of at least {MIN_TEMPLATES} templates, got {got}")
        templates = []
        for k, item in enumerate(items):
            where = f"{comparator}[{k}]"
            if not isinstance(item, dict) or set(item) != {"id", "text", "fresh"}:
                keys = sorted(item) if isinstance(item, dict) else type(item).__name__
                raise _fail(p, f"{where}: expected an object with keys ['fresh', 'id', 'text'], got {keys}")
            tid, text, fresh = item["id"], item["text"], item["fresh"]
            if not isinstance(tid, str) or not tid.strip():
                raise _fail(p, f"{where}: expected a non-empty string id, got {tid!r}")
            if tid in seen:
                raise _fail(p, f"{where}: id {tid!r} already used by a {seen[tid]} template")
            if not isinstance(fresh, bool):
                raise _fail(p, f"{where} ({tid}): 'fresh' expected true or false, got {fresh!r}")
            if not isinstance(text, str) or any(s not in text for s in _SLOTS):
                raise _fail(p, f"{where} ({tid}): text must hold both slots {{a}} and {{b}}, got {text!r}")
            if re.sub(r"\{[ab]\}", "", text).count("{") or re.sub(r"\{[ab]\}", "", text).count("}"):
                raise _fail(p, f"{where} ({tid}): only the slots {{a}} and {{b}} may use braces, got {text!r}")
            seen[tid] = comparator
            templates.append(SpatialTemplate(tid, comparator, text, fresh))
        out[comparator] = tuple(templates)
    missing = [c for c in COMPARATOR_NAMES if c not in out]
    if missing:
        raise _fail(p, f"no templates for {missing}; every comparator needs at least {MIN_TEMPLATES}")
    return {c: out[c] for c in COMPARATOR_NAMES}


def load_templates(path: str | Path = TEMPLATES_PATH) -> dict[str, tuple[SpatialTemplate, ...]]:
    """The templates by comparator (the eight, in the paper's order), checked.

    Raises:
        HarnessError: a missing or malformed file, naming the template and what was expected.
        UnknownNameError: a comparator name that is not one of the eight (naming the nearest).
    """
    return _load(str(path))
