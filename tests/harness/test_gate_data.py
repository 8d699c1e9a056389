"""The headline gate's episodes (``scenes/gate-v2/``): development seeds only, goals the tower saw
and goals it did not, pinned and calibration halves apart, and files that regenerate."""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

import pytest

from scenes import make_gate_v2 as gate
from scenes.shipped import ROOT
from sim_envs.scenes.episodes import load_episodes
from sim_envs.scenes.format import load_scene
from sim_envs.scenes.splits import object_group, splits

FILES = (gate.SEARCH_FILE, gate.SEARCH_CALIBRATION_FILE, gate.REARRANGE_FILE, gate.REARRANGE_CALIBRATION_FILE)


def _goal_groups(rel: str) -> Counter:
    out = Counter()
    for e in load_episodes(ROOT / rel).episodes:
        objects = {o.id: o for o in load_scene(ROOT / e.scene).objects}
        out.update(object_group(objects[g.object_id]) for g in e.goals)
    return out


@pytest.mark.parametrize("rel", FILES)
def test_gate_episodes_use_development_seeds_and_name_seen_and_unseen_goals(rel):
    eps = load_episodes(ROOT / rel).episodes
    want = {gate.SEARCH_FILE: gate.PINNED_APARTMENTS * 6, gate.SEARCH_CALIBRATION_FILE: gate.CALIBRATION_APARTMENTS * 6,
            gate.REARRANGE_FILE: gate.PINNED_TABLES, gate.REARRANGE_CALIBRATION_FILE: gate.CALIBRATION_TABLES}[rel]
    assert len(eps) == want
    assert {splits().seed_role(e.scene_seed) for e in eps} == {"tower_val"}
    tower_val = splits().seeds_of("tower_val", 10000)
    first = gate.APARTMENT_OFFSET if "search" in rel else gate.TABLE_OFFSET
    assert min(tower_val.index(e.scene_seed) for e in eps) >= first  # past the tower's and validation-v2's seeds
    groups = _goal_groups(rel)
    # goals the tower trained on and goals it did not, never a test instance (nor one in any scene)
    assert set(groups) == set(gate.GOAL_GROUPS) and all(groups[g] >= 0.1 * sum(groups.values()) for g in groups), groups
    for scene in {e.scene for e in eps}:
        assert {object_group(o) for o in load_scene(ROOT / scene).objects} <= set(gate.GOAL_GROUPS), scene


def test_pinned_and_calibration_episodes_share_no_scene_and_no_other_file_uses_them():
    scenes = {rel: {e.scene for e in load_episodes(ROOT / rel).episodes} for rel in FILES}
    assert not scenes[gate.SEARCH_FILE] & scenes[gate.SEARCH_CALIBRATION_FILE]
    assert not scenes[gate.REARRANGE_FILE] & scenes[gate.REARRANGE_CALIBRATION_FILE]
    ours = {Path(s).name for v in scenes.values() for s in v}
    assert {p.name for p in (ROOT / gate.FOLDER).glob("*-v2-*.json")} == ours  # no stray scene file
    elsewhere = {p.name for p in ROOT.glob("*/*-v2-*.json") if p.parent.name != gate.FOLDER}
    assert not ours & elsewhere


def test_pinned_searches_are_written_round_robin():
    eps = load_episodes(ROOT / gate.SEARCH_FILE).episodes
    first = [e.scene for e in eps[: gate.PINNED_APARTMENTS]]
    assert len(set(first)) == gate.PINNED_APARTMENTS  # the first 12 pinned searches are in 12 apartments
    assert Counter(e.scene for e in eps) == Counter({s: 6 for s in first})
    text = "header\n" + "".join(json.dumps({"scene": s, "i": i}) + "\n" for s, i in (("a", 0), ("a", 1), ("b", 0), ("c", 0), ("b", 1)))
    assert [json.loads(line)["scene"] for line in gate.round_robin(text).splitlines()[1:]] == ["a", "b", "c", "a", "b"]


def test_the_first_gate_tables_regenerate():
    files = gate.table_files(pinned=1, calibration=1)
    for rel in (gate.REARRANGE_FILE, gate.REARRANGE_CALIBRATION_FILE):
        assert files.pop(rel).splitlines() == (ROOT / rel).read_text().splitlines()[:2]
    assert len(files) == 2 and all((ROOT / rel).read_text() == text for rel, text in files.items())


def test_the_gate_searches_regenerate():
    files = gate.search_files()
    assert len(files) == 2 + gate.PINNED_APARTMENTS + gate.CALIBRATION_APARTMENTS
    assert all((ROOT / rel).read_text() == text for rel, text in files.items())
