"""How a goal object is named in an instruction: by name, synonym, attribute, function or parent.

A description singles one object out among a scene's objects, using the object library's
category metadata (:func:`sim_envs.assets.library.catalogue`):

- ``"name"``: the category name, ``"the mug"``;
- ``"synonym"``: one of the category's synonyms, ``"the coffee mug"``;
- ``"attribute"``: colour or material plus the name, ``"the red mug"``, ``"the ceramic mug"``;
- ``"function"``: what it is for, ``"something to drink from"``;
- ``"parent"``: a group above the category (not the root ``"object"``), ``"the drinkware"``.

Uniqueness is strict: every object *answers to* a set of phrases (its category name and
synonyms, colour/material + each of those, its function phrases, its parent groups); a
description is only offered when no other object in the scene answers to it. So with a mug (one
of whose synonyms is "cup") on the table, the cup cannot be called "the cup".

Objects whose asset is not a library instance (the v1 primitives) use the library category of
the same name when there is one (no material then), otherwise just their category and colour.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from sim_envs.assets.library import MATERIALS, PALETTE, catalogue, instance_of_asset, is_library_asset
from sim_envs.scenes.format import SceneObject

__all__ = ["DESCRIPTION_KINDS", "Describable", "describable", "answer_phrases", "candidates", "describe", "referents"]

DESCRIPTION_KINDS: tuple[str, ...] = ("name", "synonym", "attribute", "function", "parent")
"""The kinds of description, in a fixed order."""

_ROOT = "object"
_ODD_MATERIALS = frozenset({"organic"})  # "the organic apple" says nothing useful
_ADJECTIVES = {"wooden": "wood", "metallic": "metal", "golden": "gold", "ceramics": "ceramic"}


@dataclass(frozen=True)
class Describable:
    """What a scene object can be called (lower case phrases)."""

    name: str
    """Its category name ("mug")."""
    synonyms: tuple[str, ...]
    """Other names of its category."""
    color: str
    """Its colour name."""
    material: str | None
    """Its material (None when unknown: a non-library asset)."""
    functions: tuple[str, ...]
    """What it is for ("something to drink from")."""
    parents: tuple[str, ...]
    """Groups above its category, nearest first, without the root ("drinkware", "container")."""

    def phrases(self, kind: str) -> tuple[str, ...]:
        """Descriptions of this object of one kind (not checked for uniqueness), sorted; synonyms
        whose colour or material words contradict the object are left out."""
        if kind == "name":
            return (f"the {self.name}",)
        if kind == "synonym":
            return tuple(sorted({f"the {s}" for s in self.synonyms if s != self.name and self._consistent(s)}))
        if kind == "attribute":
            out = {f"the {self.color} {self.name}"}
            if self.material is not None and self.material not in _ODD_MATERIALS:
                out.add(f"the {self.material} {self.name}")
            return tuple(sorted(out))
        if kind == "function":
            return tuple(sorted(set(self.functions)))
        if kind == "parent":
            return tuple(sorted({f"the {p}" for p in self.parents}))
        raise ValueError(f"unknown description kind {kind!r}; expected one of {DESCRIPTION_KINDS}")

    def _consistent(self, synonym: str) -> bool:
        """Whether a synonym's colour and material words fit this object ("paper cup" does not
        fit a plastic cup, "red apple" not a green one)."""
        for word in synonym.split():
            word = _ADJECTIVES.get(word, word)
            if word in MATERIALS and word != self.material:
                return False
            if word in PALETTE and word != self.color:
                return False
        return True

    def answers_to(self) -> frozenset[str]:
        """Every phrase that could be taken to mean this object (all kinds, attributes over
        synonyms too)."""
        nouns = (self.name,) + self.synonyms
        out = {f"the {n}" for n in nouns} | set(self.functions) | {f"the {p}" for p in self.parents}
        out |= {f"the {self.color} {n}" for n in nouns}
        if self.material is not None:
            out |= {f"the {self.material} {n}" for n in nouns}
        return frozenset(out)


def describable(obj: SceneObject) -> Describable:
    """The names, attributes, functions and parents of a scene object, from the library."""
    cat_name = obj.category.strip().lower()
    material = None
    if is_library_asset(obj.asset):
        inst = instance_of_asset(obj.asset)
        cat_name, material = inst.category, inst.material
    cat = catalogue().categories.get(cat_name)
    if cat is None:
        return Describable(cat_name, (), obj.color, material, (), ())
    parents = tuple(p for p in catalogue().ancestors(cat.name) if p != _ROOT)
    return Describable(cat.name, tuple(cat.synonyms), obj.color, material, tuple(cat.functions), parents)


def answer_phrases(obj: SceneObject) -> list[str]:
    """Every phrase ``obj`` answers to (:meth:`Describable.answers_to`), sorted: what the
    environments give privileged agents as ``info["object_phrases"]`` and what ground-truth
    grounding of descriptions (the ``oracle-open`` perception) reads."""
    return sorted(describable(obj).answers_to())


def candidates(obj: SceneObject, scene_objects: Sequence[SceneObject], kind: str) -> tuple[str, ...]:
    """Every description of ``kind`` that singles ``obj`` out among ``scene_objects``, sorted.

    ``obj`` is matched among ``scene_objects`` by id (it need not be in the list).

    Raises:
        ValueError: unknown ``kind``.
    """
    mine = describable(obj).phrases(kind)
    taken: set[str] = set()
    for other in scene_objects:
        if other.id != obj.id:
            taken |= describable(other).answers_to()
    return tuple(p for p in mine if p not in taken)


def describe(obj: SceneObject, scene_objects: Sequence[SceneObject], kind: str, rng: np.random.Generator) -> str | None:
    """A description of ``kind`` that singles ``obj`` out among ``scene_objects``.

    Returns None when no description of that kind can (two mugs and kind ``"name"``). With
    several candidates one is drawn with ``rng`` (one ``rng.integers`` call, only when there is
    at least one candidate), so the result is deterministic given the generator's state.

    Raises:
        ValueError: unknown ``kind``.
        TypeError: ``rng`` is not a ``numpy.random.Generator``.
    """
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng: expected a numpy.random.Generator, got {type(rng).__name__}")
    options = candidates(obj, scene_objects, kind)
    if not options:
        return None
    return options[int(rng.integers(len(options)))]


def referents(description: str, scene_objects: Sequence[SceneObject]) -> list[SceneObject]:
    """The objects of a scene that answer to ``description`` (one, for a description made by
    :func:`describe`)."""
    return [o for o in scene_objects if description in describable(o).answers_to()]
