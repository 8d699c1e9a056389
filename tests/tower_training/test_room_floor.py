"""The v2 tower's apartment score floor: where it is derived, that it reproduces, and who reads it."""

from __future__ import annotations

import json
import math
import re
from types import SimpleNamespace

import numpy as np
import pytest

from agents.builtin import make_mapper
from agents.registry import make_agent
from conceptfusion.perception.featurizer import SEARCH_PROPOSER, PerceivedFeaturizer, make_featurizer, score_floor_for
from conceptfusion.perception.score_floor import encoder_score_floor
from conceptfusion.perception.image_tower import SHIPPED_TOWER_V2_DIR
from sim_envs.scenes.splits import splits
from tower_training.score_floor import FloorConfigV2
from tower_training.room_floor import FLOOR_KEY, RoomFloorConfig, apartment_query_scores, floor_key, room_floor_seeds, setting_config

SHIPPED = json.loads((SHIPPED_TOWER_V2_DIR / "tower.json").read_text())["metrics"]


def test_apartment_seeds_are_calibration_seeds_apart_from_the_table_calibration():
    seeds = room_floor_seeds(RoomFloorConfig())
    assert seeds == SHIPPED[FLOOR_KEY + "_calibration"]["seeds"] and len(seeds) == 12
    assert room_floor_seeds(setting_config("search")) == SHIPPED[floor_key("search") + "_calibration"]["seeds"] == seeds
    assert {splits().seed_role(s) for s in seeds} == {"calibration"}
    assert not set(seeds) & set(splits().seeds_of("calibration", FloorConfigV2().scenes))
    with pytest.raises(ValueError, match="scenes: expected an integer >= 2"):
        RoomFloorConfig(scenes=1)
    with pytest.raises(ValueError, match="seed_offset: expected an integer >= 0"):
        RoomFloorConfig(seed_offset=-1)
    with pytest.raises(ValueError, match="setting: expected an apartment setting .household, search., got 'tabletop'"):
        RoomFloorConfig(setting="tabletop")


def test_the_search_setting_is_the_search_agents_view():
    search, household = setting_config("search"), setting_config("household")
    assert (search.view.width, search.view.height, search.proposer, search.setting) == (320, 240, SEARCH_PROPOSER, "search")
    assert (household.view.width, household.view.height, household.proposer) == (160, 120, "rgbd")
    assert household == RoomFloorConfig()
    from harness.runner.suites import get_suite

    env = get_suite("search-v2").env_kwargs  # the floor is derived for the frames the suite renders
    assert (env["width"], env["height"]) == (search.view.width, search.view.height)
    assert SHIPPED[floor_key("search") + "_calibration"]["config"]["proposer"] == SEARCH_PROPOSER


def test_floors_per_setting():
    v2 = make_featurizer("embedded-v2")
    assert score_floor_for(v2, "household") == SHIPPED[FLOOR_KEY] and score_floor_for(v2, "tabletop") == SHIPPED["score_floor"]
    assert v2.score_floor == SHIPPED["score_floor"]
    v1 = make_featurizer("embedded")  # no apartment floor: its table floor everywhere
    assert score_floor_for(v1, "household") == score_floor_for(v1, "tabletop") == v1.score_floor
    given = PerceivedFeaturizer(v2.encoder, v2.proposer, score_floor=0.2)  # an explicit floor holds everywhere
    assert score_floor_for(given, "household") == score_floor_for(given, "tabletop") == 0.2
    oracle = make_featurizer("oracle-open")
    assert score_floor_for(oracle, "household") == oracle.score_floor
    assert score_floor_for(SimpleNamespace(score_floor=0.4), "household") == 0.4
    with pytest.raises(ValueError, match="setting: expected one of tabletop, household, search, got 'kitchen'"):
        score_floor_for(v2, "kitchen")
    assert make_mapper("embedded-v2", setting="household").config.min_score == SHIPPED[FLOOR_KEY]
    assert score_floor_for(v2, "search") == SHIPPED["score_floor_search"] != SHIPPED[FLOOR_KEY]
    assert score_floor_for(v1, "search") == v1.score_floor
    # a setting without its own floor falls back to household, then tabletop
    tower = SimpleNamespace(info={"metrics": {"score_floor": 0.5, "score_floor_household": 0.3}})
    assert (encoder_score_floor(tower, "search"), encoder_score_floor(tower, "household"), encoder_score_floor(tower, "tabletop")) == (0.3, 0.3, 0.5)
    assert encoder_score_floor(SimpleNamespace(info={"metrics": {}}), "search") is None
    # the search agents see apartments with their own proposals; the pushers work on tables
    nav = make_agent("map-navigator", encoder="embedded-v2")
    assert nav.mapper.config.min_score == SHIPPED["score_floor_search"]
    assert nav.mapper.featurizer.proposer.config.fixed_size_pixels == 19200
    assert make_agent("frame-searcher", encoder="embedded-v2").mapper.config.min_score == SHIPPED["score_floor_search"]
    assert make_agent("map-pusher", encoder="embedded-v2").mapper.config.min_score == SHIPPED["score_floor"]


@pytest.mark.parametrize("setting", ["household", "search"])
def test_the_first_calibration_apartment_reproduces_its_recorded_scores(setting):
    from conceptfusion.perception.featurizer import PerceptionSpec

    config = setting_config(setting)
    featurizer = make_featurizer(PerceptionSpec.parse("embedded-v2", proposer=config.proposer))
    from sim_envs.assets.library import catalogue

    r = apartment_query_scores(room_floor_seeds(config)[0], featurizer, sorted(catalogue().categories), config,
                               np.random.default_rng(config.rng_seed))
    assert r["present"] and r["absent"] and "chair" not in r["absent"]  # furniture names are not absent
    recorded = SHIPPED[floor_key(setting) + "_calibration"]["calibration"]
    listed = [m for m in recorded["missed_present"] + recorded["found_absent"] if m.startswith(r["scene"] + ": ")]
    assert listed
    floor = SHIPPED[floor_key(setting)]
    for entry in listed:
        name, value = re.fullmatch(rf"{r['scene']}: (.+) \((not found|[0-9.]+)\)", entry).groups()
        score = r["present"].get(name, r["absent"].get(name))
        if value == "not found":
            assert score == -math.inf
        else:
            assert round(score, 2) == pytest.approx(float(value), abs=0.006)
        assert (score >= floor) == (name in r["absent"])  # missed present below, found absent above


def test_size_reaches_the_views_and_bad_sizes_are_refused(monkeypatch, capsys):
    import tower_training.room_floor as rf

    seen = {}
    split = {"present_found": 0.7, "n_present": 10, "absent_rejected": 0.9, "n_absent": 50,
             "absent_rejected_same_parent": 0.8, "n_absent_same_parent": 5, "balanced_accuracy": 0.8}

    def fake(config, *, encoder=None):
        seen["config"] = config
        return {"score_floor": 0.2, "calibration": split, "validation": split}

    monkeypatch.setattr(rf, "calibrate_room_floor", fake)
    monkeypatch.setattr(rf, "write_room_floor", lambda *a, **k: pytest.fail("--dry-run must not write"))
    assert rf.main(["--dry-run", "--size", "320x240", "--views", "5"]) == 0
    config = seen["config"]
    assert (config.view.width, config.view.height, config.views) == (320, 240, 5)
    # Only the image size changes: the camera placement stays the search camera's.
    assert config.view.eye_height_m == RoomFloorConfig().view.eye_height_m
    assert "floor 0.200" in capsys.readouterr().out
    assert rf.main(["--dry-run"]) == 0 and (seen["config"].view.width, seen["config"].view.height) == (160, 120)
    with pytest.raises(SystemExit):
        rf.main(["--dry-run", "--size", "320by240"])
    assert re.search(r"--size: expected WIDTHxHEIGHT in pixels such as 320x240, got '320by240'", capsys.readouterr().err)
    # --setting search: the search agents' size and proposals, unless given
    assert rf.main(["--dry-run", "--setting", "search"]) == 0
    assert (seen["config"].view.width, seen["config"].proposer, seen["config"].setting) == (320, SEARCH_PROPOSER, "search")
    assert rf.main(["--dry-run", "--setting", "search", "--proposer", "rgbd", "--size", "160x120"]) == 0
    assert (seen["config"].view.width, seen["config"].proposer) == (160, "rgbd")
    with pytest.raises(SystemExit):
        rf.main(["--dry-run", "--proposer", "rgbd:fine=3"])
    assert "--proposer: proposer 'rgbd': 'fine' is not a setting" in capsys.readouterr().err
