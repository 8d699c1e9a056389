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
from conceptfusion.perception.featurizer import PerceivedFeaturizer, make_featurizer, score_floor_for
from conceptfusion.perception.image_tower import SHIPPED_TOWER_V2_DIR
from sim_envs.scenes.splits import splits
from tower_training.score_floor import FloorConfigV2
from tower_training.room_floor import FLOOR_KEY, RoomFloorConfig, apartment_query_scores, room_floor_seeds

SHIPPED = json.loads((SHIPPED_TOWER_V2_DIR / "tower.json").read_text())["metrics"]


def test_apartment_seeds_are_calibration_seeds_apart_from_the_table_calibration():
    seeds = room_floor_seeds(RoomFloorConfig())
    assert seeds == SHIPPED[FLOOR_KEY + "_calibration"]["seeds"] and len(seeds) == 12
    assert {splits().seed_role(s) for s in seeds} == {"calibration"}
    assert not set(seeds) & set(splits().seeds_of("calibration", FloorConfigV2().scenes))
    with pytest.raises(ValueError, match="scenes: expected an integer >= 2"):
        RoomFloorConfig(scenes=1)
    with pytest.raises(ValueError, match="seed_offset: expected an integer >= 0"):
        RoomFloorConfig(seed_offset=-1)


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
    with pytest.raises(ValueError, match="setting: expected one of tabletop, household, got 'kitchen'"):
        score_floor_for(v2, "kitchen")
    assert make_mapper("embedded-v2", setting="household").config.min_score == SHIPPED[FLOOR_KEY]
    # the search agents work in apartments; the pushers on tables
    assert make_agent("map-navigator", encoder="embedded-v2").mapper.config.min_score == SHIPPED[FLOOR_KEY]
    assert make_agent("frame-searcher", encoder="embedded-v2").mapper.config.min_score == SHIPPED[FLOOR_KEY]
    assert make_agent("map-pusher", encoder="embedded-v2").mapper.config.min_score == SHIPPED["score_floor"]


def test_the_first_calibration_apartment_reproduces_its_recorded_scores():
    config = RoomFloorConfig()
    featurizer = make_featurizer("embedded-v2")
    from sim_envs.assets.library import catalogue

    r = apartment_query_scores(room_floor_seeds(config)[0], featurizer, sorted(catalogue().categories), config,
                               np.random.default_rng(config.rng_seed))
    assert r["present"] and r["absent"] and "chair" not in r["absent"]  # furniture names are not absent
    recorded = SHIPPED[FLOOR_KEY + "_calibration"]["calibration"]
    listed = [m for m in recorded["missed_present"] + recorded["found_absent"] if m.startswith(r["scene"] + ": ")]
    assert listed
    floor = SHIPPED[FLOOR_KEY]
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
