"""Captions of object-library instances: the texts a crop of an instance is trained to match (v2).

Every instance gets several captions, each tagged with its kind (:data:`CAPTION_KINDS`):

* ``name``: its category's name, bare and with an article ("mug", "a mug");
* ``synonym``: the category's synonyms ("coffee mug", "cup");
* ``parent``: the groups above the category, nearest first, without the root "object"
  ("drinkware", "container");
* ``colour``: colour + name ("a red mug");
* ``material``: material + name ("a ceramic mug");
* ``function``: what it is for ("something to drink from").

Captions are shared between instances (every mug has "mug"): the loss
(:func:`tower_training.training.train_tower_multicaption`) treats every caption of a crop's
instance as a positive and masks the others out of the negatives.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

__all__ = ["CAPTION_KINDS", "Caption", "article", "instance_captions", "CaptionBank", "caption_bank"]

CAPTION_KINDS = ("name", "synonym", "parent", "colour", "material", "function")
"""Kinds of caption, in the order :func:`instance_captions` lists them."""

_ROOT = "object"
"""The taxonomy's root: a parent caption that says nothing."""

_MATERIAL_WORD = {"organic": "", "clear": "clear"}
"""Materials whose word does not read as an adjective ("organic apple" -> "apple")."""


@dataclass(frozen=True)
class Caption:
    """One text of an instance and what kind of caption it is."""

    text: str
    kind: str


def article(phrase: str) -> str:
    """``"a mug"`` / ``"an apple"``."""
    return ("an " if phrase[:1].lower() in "aeiou" else "a ") + phrase


def instance_captions(instance, catalogue) -> list[Caption]:
    """Every caption of one library instance (see the module docstring), distinct texts.

    Args:
        instance: a :class:`sim_envs.assets.library.Instance`.
        catalogue: the :class:`sim_envs.assets.library.Catalogue` it belongs to.
    """
    cat = catalogue.categories[instance.category]
    name = cat.name
    out: list[Caption] = [Caption(name, "name"), Caption(article(name), "name")]
    out += [Caption(s, "synonym") for s in cat.synonyms]
    out += [Caption(g, "parent") for g in catalogue.ancestors(name) if g != _ROOT]
    out.append(Caption(article(f"{instance.color} {name}"), "colour"))
    word = _MATERIAL_WORD.get(instance.material, instance.material)
    if word:
        out.append(Caption(article(f"{word} {name}"), "material"))
    out += [Caption(f, "function") for f in cat.functions]
    seen, uniq = set(), []
    for c in out:
        if c.text not in seen:
            seen.add(c.text)
            uniq.append(c)
    return uniq


@dataclass(frozen=True)
class CaptionBank:
    """The distinct captions of a set of instances and which instance each is a positive of.

    Shape:
        ``texts`` T strings, ``kinds`` T strings; ``positives`` (C, T) bool: class c (an
        instance, in ``class_names`` order) has caption t.
    """

    class_names: tuple[str, ...]
    texts: tuple[str, ...]
    kinds: tuple[str, ...]
    positives: np.ndarray

    def of(self, class_name: str) -> list[str]:
        """The captions of one class."""
        c = self.class_names.index(class_name)
        return [self.texts[t] for t in np.flatnonzero(self.positives[c])]


def caption_bank(class_captions: Sequence[tuple[str, Sequence[Caption]]]) -> CaptionBank:
    """Collect the distinct captions of ``(class name, captions)`` pairs into a bank.

    A text listed under two kinds keeps the first kind seen.
    """
    texts: dict[str, int] = {}
    kinds: list[str] = []
    for _, caps in class_captions:
        for c in caps:
            if c.text not in texts:
                texts[c.text] = len(texts)
                kinds.append(c.kind)
    pos = np.zeros((len(class_captions), len(texts)), bool)
    for i, (_, caps) in enumerate(class_captions):
        if not caps:
            raise ValueError(f"class {class_captions[i][0]!r}: expected at least one caption")
        pos[i, [texts[c.text] for c in caps]] = True
    return CaptionBank(tuple(n for n, _ in class_captions), tuple(texts), tuple(kinds), pos)
