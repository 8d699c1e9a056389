"""The object library's catalogue: counts, complete metadata, a sound taxonomy, stable ids."""

from __future__ import annotations

import dataclasses

import pytest

from conceptfusion.errors import SimError
from sim_envs.assets.library import LICENCES, MATERIALS, PALETTE, build_catalogue, catalogue, catalogue_hash, get_instance
from sim_envs.assets.library.catalogue import draw_instances, scene_instance
from sim_envs.assets.library.catalogue_kitchen import GROUPS, KITCHEN_CATEGORIES
from sim_envs.assets.library.shapes import SHAPES
from sim_envs.assets.library.taxonomy import Group

GOLDEN_HASH = "dc9c516c48e3e39e5a82750f8e8427901dfca0964191d60ea5d2a8917a9f65d8"
"""SHA-256 of the catalogue's records; update only on purpose (it moves every split built on it)."""


def test_counts():
    cat = catalogue()
    assert len(cat.categories) >= 60 and len(cat.instances) >= 400
    procedural = [c for c in cat.categories.values() if c.count]
    assert len(procedural) >= 60
    assert all(len(cat.instances_of(c.name)) >= 1 for c in cat.categories.values())


def test_every_category_has_complete_metadata():
    for c in catalogue().categories.values():
        assert c.name.strip() and c.synonyms and c.parents and c.functions, c.name
        assert c.materials and set(c.materials) <= set(MATERIALS), c.name
        assert c.colors and set(c.colors) <= set(PALETTE), c.name
        assert 0 < c.size_range[0] <= c.size_range[1] < 2.0, c.name
        assert c.source and c.licence in LICENCES, c.name
        assert set(c.variants) <= set(SHAPES), c.name


def test_taxonomy_is_acyclic_and_every_parent_exists():
    cat = catalogue()
    for name in [*cat.groups, *cat.categories]:
        chain = cat.ancestors(name)
        assert name not in chain and len(chain) == len(set(chain))
        assert all(p in cat.groups for p in chain)
        if name != "object":
            assert "object" in chain  # every path reaches the root
    assert cat.ancestors("mug")[:2] == ("drinkware", "container")


def test_instances_are_unique_valid_and_stable():
    cat = catalogue()
    ids = list(cat.instances)
    assert len(ids) == len(set(ids))
    for inst in cat.instances.values():
        c = cat.categories[inst.category]
        assert c.size_range[0] <= inst.scale <= c.size_range[1]
        assert LICENCES[inst.licence].allows_training
        assert inst.asset == f"lib:{inst.id}"
    assert get_instance("mug-003").category == "mug" and get_instance("lib:mug-003").id == "mug-003"
    assert catalogue_hash() == GOLDEN_HASH
    again = [i for c in KITCHEN_CATEGORIES for i in draw_instances(c)]
    assert again == [i for i in cat.instances.values() if i.category in {c.name for c in KITCHEN_CATEGORIES} and i.mesh is None]


def test_every_variant_of_a_category_is_drawn():
    cat = catalogue()
    for c in cat.categories.values():
        assert {i.variant for i in cat.instances_of(c.name) if i.mesh is None} == set(c.variants), c.name


def test_a_category_without_a_name_is_refused():
    bad = dataclasses.replace(KITCHEN_CATEGORIES[0], name="  ")
    with pytest.raises(SimError, match=r"test\.json: category #0\.name: expected a non-empty name"):
        build_catalogue(GROUPS, [bad], source="test.json")


def test_an_unknown_parent_and_a_cycle_are_refused():
    bad = dataclasses.replace(KITCHEN_CATEGORIES[0], parents=("drinkwear",))
    with pytest.raises(SimError, match=r"category 'mug'\.parents: unknown parent 'drinkwear'; did you mean 'drinkware'"):
        build_catalogue(GROUPS, [bad])
    cyclic = [*GROUPS, Group("a", ("x",), ("b",)), Group("b", ("y",), ("a",))]
    with pytest.raises(SimError, match="cycle: a -> b -> a"):
        build_catalogue(cyclic, KITCHEN_CATEGORIES[:1])


def test_an_instance_naming_an_unknown_category_is_refused():
    inst = dataclasses.replace(draw_instances(KITCHEN_CATEGORIES[0])[0], category="mugg")
    with pytest.raises(SimError, match=r"instance 'mug-000'\.category: unknown category 'mugg'; did you mean 'mug'"):
        build_catalogue(GROUPS, KITCHEN_CATEGORIES[:1], [inst])


def test_unknown_instance_and_wrong_colour_name_the_field():
    with pytest.raises(KeyError, match="unknown library instance 'mug-999'.*mug-00"):
        get_instance("mug-999")
    with pytest.raises(SimError, match=r"scene\.json: objects\[2\]\.asset: unknown library instance 'mgu-001'; did you mean 'mug-001'"):
        scene_instance("lib:mgu-001", "red", "scene.json: objects[2]")
    color = get_instance("mug-001").color
    with pytest.raises(SimError, match=rf"objects\[2\]\.color: library instance 'mug-001' is '{color}', got 'purple'"):
        scene_instance("lib:mug-001", "purple", "scene.json: objects[2]")
