"""What a replay's saved map records of how it was made and asked (its ``meta``), from the
mapper the agent used: so that the viewer answers as the agent did."""

from agents.builtin import make_mapper
from harness.replay.record import map_meta


def test_map_meta_names_the_encoder_setting_floor_and_the_lookup_used():
    mapper = make_mapper("color", setting="search")
    meta = map_meta(mapper, "map-navigator")
    assert meta == {"encoder": "color", "proposer": "rgbd", "setting": "search", "min_score": mapper.config.min_score,
                    "lookup": "plain", "agent": "map-navigator"}
    mapper.locate_present("red box", name_only=False)  # an agent that presumes its goal is there
    assert map_meta(mapper)["lookup"] == "present" and map_meta(mapper)["name_only"] is False
    assert "agent" not in map_meta(mapper)


def test_a_mapper_built_from_a_featurizer_records_no_encoder():
    from conceptfusion.perception.featurizer import PerceptionSpec, make_featurizer

    mapper = make_mapper(make_featurizer(PerceptionSpec("color")))
    assert "encoder" not in map_meta(mapper) and map_meta(mapper)["setting"] == "tabletop"
