"""The one nearest-name helper: suggestions, messages and lookups."""

from __future__ import annotations

import pytest

from conceptfusion.errors import ConceptFusionError, UnknownKeyError, UnknownNameError
from conceptfusion.names import did_you_mean, lookup, nearest_names, unknown_name_error

TABLE = {"rgbd": 1, "sam": 2, "gt": 3}


def test_nearest_names_and_did_you_mean():
    assert nearest_names("rbgd", TABLE) == ["rgbd"]
    assert nearest_names("zzzz", TABLE) == []
    assert did_you_mean("rbgd", TABLE) == "; did you mean 'rgbd'?"
    assert did_you_mean("zzzz", TABLE) == ""


def test_a_key_compares_normalised_names_and_returns_the_given_ones():
    names = ["isToTheRight", "isToTheLeft", "onTopOf"]
    assert nearest_names("istotherigt", names, key=str.lower, n=1, cutoff=0.8) == ["isToTheRight"]
    assert nearest_names("istotherigt", names, n=1, cutoff=0.8) == []


def test_unknown_name_error_message_and_class():
    err = unknown_name_error("mask proposer", "rbgd", TABLE)
    assert isinstance(err, UnknownNameError) and isinstance(err, ValueError) and isinstance(err, ConceptFusionError)
    assert str(err) == "unknown mask proposer 'rbgd'; did you mean 'rgbd'? (mask proposers: rgbd, sam, gt)"
    assert str(unknown_name_error("suite", "x", ["a"], listing="")) == "unknown suite 'x'"
    err = unknown_name_error("asset", "dcuk", ["duck"], listing="known: duck", error=UnknownKeyError)
    assert isinstance(err, KeyError) and str(err) == "unknown asset 'dcuk'; did you mean 'duck'? (known: duck)"


def test_lookup():
    assert lookup(TABLE, "sam", "mask proposer") == 2
    with pytest.raises(UnknownNameError, match=r"unknown mask proposer 'sma'; did you mean 'sam'\?"):
        lookup(TABLE, "sma", "mask proposer")
    with pytest.raises(UnknownNameError, match="unknown mask proposer"):
        lookup(TABLE, ["unhashable"], "mask proposer")
