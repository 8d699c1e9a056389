"""``conceptfusion.make_mapper``: the one builder of mappers puts the encoder's calibrated score
floor on by default (per setting), takes the mapper's settings by name, and a mapper saves its map
with what the viewer needs to ask it the same way."""

from __future__ import annotations

import numpy as np
import pytest

from conceptfusion import make_mapper, register_encoder
from conceptfusion.map.persistence import load_map, read_map_meta
from conceptfusion.mapper import ConceptMapper
from conceptfusion.perception import registry
from conceptfusion.perception.encoders import ColorNameEncoder
from conceptfusion.perception.featurizer import score_floor_for
from tests.conceptfusion.test_frame_folders import box_frames


class _Calibrated(ColorNameEncoder):
    """The colour encoder with floors calibrated for tabletops and households (none for search)."""

    info = {"metrics": {"score_floor": 0.9, "score_floor_household": 0.85}}


@pytest.fixture
def calibrated():
    """A registered encoder with calibrated floors; the registry is put back afterwards."""
    saved, checks = dict(registry.ENCODERS), dict(registry._AVAILABLE)
    register_encoder("calibrated-color", lambda arg: _Calibrated(), description="colour encoder with floors (tests)")
    yield "calibrated-color"
    registry.ENCODERS.clear()
    registry.ENCODERS.update(saved)
    registry._AVAILABLE.clear()
    registry._AVAILABLE.update(checks)


@pytest.mark.parametrize("setting, floor", [("tabletop", 0.9), ("household", 0.85), ("search", 0.85)])
def test_the_calibrated_floor_is_on_by_default(calibrated, setting, floor):
    mapper = make_mapper(calibrated, setting=setting)
    assert isinstance(mapper, ConceptMapper)
    assert mapper.config.min_score == floor == score_floor_for(mapper.featurizer, setting)
    assert mapper.meta() == {"encoder": calibrated, "proposer": "rgbd", "setting": setting, "min_score": floor, "lookup": "plain"}


def test_the_floor_decides_what_only_beats_the_generic_phrases(calibrated):
    mapper = make_mapper(calibrated)
    for frame in box_frames()[:2]:
        mapper.integrate(frame)
    for text in ("red box", "green box"):
        assert mapper.locate(text, floor=False).found  # each beats "object", "things" ...
    red = mapper.locate("red box", floor=False).best
    assert float(np.median(red.scores_n)) < 0.9 <= float(np.median(mapper.locate("green box").best.scores_n))
    floored = mapper.locate("red box")
    assert not floored.found and "below the encoder's floor 0.90" in floored.reason


def test_settings_by_name_and_the_floor_replaced_or_off(calibrated):
    mapper = make_mapper(calibrated, max_depth=2.0, voxel_size=0.05, min_score=None)
    assert mapper.config.max_depth == 2.0 and mapper.config.voxel_size == 0.05 and mapper.config.min_score is None
    assert mapper.map.config.max_depth == 2.0
    assert make_mapper(calibrated, min_score=0.9).meta()["min_score"] == 0.9
    with pytest.raises(TypeError, match=r"unknown mapper setting 'max_dept'; did you mean 'max_depth'.*\(MapperConfig fields: persistent, max_depth"):
        make_mapper("color", max_dept=2.0)


def test_the_agents_builder_is_the_same(calibrated):
    from agents import make_mapper as agents_make_mapper

    ours, theirs = make_mapper(calibrated, setting="household"), agents_make_mapper(calibrated, setting="household")
    assert ours.config == theirs.config and ours.provenance == theirs.provenance


def test_a_mapper_saves_its_map_with_its_meta(calibrated, tmp_path):
    mapper = make_mapper(calibrated, setting="household")
    mapper.integrate(box_frames()[0])
    mapper.locate_present("red box", name_only=False)
    path = mapper.save(tmp_path / "mine.map.npz")
    assert len(load_map(path)) == len(mapper.map) > 0
    assert read_map_meta(path) == {"encoder": calibrated, "proposer": "rgbd", "setting": "household", "min_score": 0.85,
                                   "lookup": "present", "name_only": False}
