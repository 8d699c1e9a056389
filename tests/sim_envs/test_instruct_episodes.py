"""Instruction episodes: the format's version 3 fields, the any-of goal in ObjectSearch, the room
plan observation, and the generator's promises (every satisfying object listed, the nearest one
the goal, starts away from all of them)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from conceptfusion.errors import SimError
from sim_envs.envs.object_search import ObjectSearchEnv, box_distance_xy
from sim_envs.scenes.descriptions import describable, referents
from sim_envs.scenes.episodes import INSTRUCTION_KINDS, SCENES_ROOT, EpisodeFormatError, load_episodes
from conceptfusion.tasks import ROOM_TYPES, rooms_from_plan
from sim_envs.scenes.format import load_scene
from sim_envs.scenes.instruct_episodes import FAR, GROUP_NEEDS, NEAR, instructions_of

EVAL = SCENES_ROOT / "instruct-v2" / "instruct-episodes-v2.jsonl"
DEV = SCENES_ROOT / "calibration-v2" / "instruct-episodes-v2.jsonl"


@pytest.fixture(scope="module")
def episodes():
    return load_episodes(EVAL)


def test_shipped_sets_are_large_mixed_and_disjoint(episodes):
    dev = load_episodes(DEV)
    assert len(episodes.episodes) >= 150 and len(dev.episodes) >= 100
    for eps in (episodes, dev):
        kinds = {e.instruction_kind for e in eps.episodes}
        assert kinds == set(INSTRUCTION_KINDS)
        assert all(len(e.goals) == 1 for e in eps.episodes)
    assert {e.scene for e in episodes.episodes}.isdisjoint({e.scene for e in dev.episodes})
    assert any(e.goals[0].accept for e in episodes.episodes)  # some instructions several objects satisfy


def test_every_goal_lists_exactly_the_satisfying_objects(episodes):
    """Recomputed from the scene: the goal plus ``accept`` is the instruction's satisfying set, and
    nothing else in the apartment satisfies it."""
    for e in episodes.episodes[:40]:
        scene = load_scene(SCENES_ROOT / e.scene)
        matching = [i for i in instructions_of(scene)[e.instruction_kind] if i.text == e.instruction]
        assert matching, e.episode_id
        assert set(matching[0].satisfying) == {e.goals[0].object_id, *e.goals[0].accept}, e.episode_id


def test_needs_and_relations_follow_the_library_and_the_scene_graph():
    scene = load_scene(SCENES_ROOT / "instruct-v2" / "household-v2-305000.json")
    out = instructions_of(scene)
    by_id = {o.id: o for o in scene.objects}
    for ins in out["need"]:
        phrase = next(p for p in [*{f for o in scene.objects for f in describable(o).functions}, *GROUP_NEEDS.values()]
                      if ins.text.endswith(p))
        if phrase in GROUP_NEEDS.values():
            group = next(g for g, p in GROUP_NEEDS.items() if p == phrase)
            assert set(ins.satisfying) == {o.id for o in scene.objects if group in describable(o).parents}
        else:
            assert set(ins.satisfying) == {o.id for o in referents(phrase, scene.objects)}
    for ins in out["relation"]:
        if " next to the " in ins.text:
            anchor = next(o for o in scene.objects if ins.text.endswith(f"next to the {o.category}"))
            for oid in ins.satisfying:
                (alo, ahi), (blo, bhi) = by_id[oid].footprint(), anchor.footprint()
                gap = np.maximum(np.maximum(alo - bhi, blo - ahi), 0.0)
                assert math.hypot(*gap) <= NEAR + 1e-9
        else:
            assert all(by_id[oid].support is not None for oid in ins.satisfying)
    assert FAR > NEAR


def test_format_v3_round_trip_and_bad_fields(tmp_path, episodes):
    from sim_envs.scenes.episodes import save_episodes

    save_episodes(episodes, tmp_path / "e.jsonl")
    again = load_episodes(tmp_path / "e.jsonl")
    assert again == episodes
    header, first = (tmp_path / "e.jsonl").read_text().splitlines()[:2]
    assert json.loads(header)["version"] == 3
    row = json.loads(first)
    for bad, match in [
        ({**row, "instruction_kind": "errand"}, r"'instruction_kind' expected null or one of \('need', 'room', 'relation'\)"),
        ({**row, "goals": [{"object_id": "obj1", "accept": ["obj1"]}]}, r"goals\[0\]\.accept expected a list of distinct object ids"),
        ({**row, "goals": [{"object_id": "obj1", "accept": "obj2"}]}, r"goals\[0\]\.accept expected a list"),
    ]:
        (tmp_path / "bad.jsonl").write_text(header + "\n" + json.dumps(bad) + "\n")
        with pytest.raises(EpisodeFormatError, match=match):
            load_episodes(tmp_path / "bad.jsonl")


def test_any_accepted_object_reaches_the_goal(episodes):
    ep = next(e for e in episodes.episodes if e.goals[0].accept)
    env = ObjectSearchEnv(episodes=[ep], width=32, height=24, segmentation=False)
    try:
        obs, info = env.reset(options={"episode": ep})
        scene = env.scene
        ids = [o.id for o in scene.objects]
        other = ep.goals[0].accept[0]
        box = np.array(scene.objects[ids.index(other)].footprint())
        pose = env._pose
        assert info["distance_to_goal"] == pytest.approx(min(box_distance_xy(pose[:2], *b[:, :2]) for b in env._accepted_boxes))
        # teleport next to the accepted (not the nearest) object and stop there
        free = np.argwhere(env._free)
        cx, cy = env._occ.centres()
        cells = [(float(cx[r, c]), float(cy[r, c])) for r, c in free]
        near = min(cells, key=lambda xy: box_distance_xy(np.array(xy), box[0], box[1]))
        env._pose = np.array([near[0], near[1], 0.0])
        _, reward, done, _, info = env.step(np.array([0.0, 0.0, 1.0], np.float32))
        assert done and info["success"] and reward == 1.0
    finally:
        env.close()


def test_room_plan_observation_and_checker(episodes):
    ep = episodes.episodes[0]
    env = ObjectSearchEnv(episodes=[ep], width=32, height=24, room_plan=True)
    try:
        check_env(env, skip_render_check=True)
        obs, _ = env.reset(options={"episode": ep})
        rooms = rooms_from_plan(obs)
        assert [name for name, _ in rooms] == [r.name for r in env.scene.rooms]
        for (name, box), room in zip(rooms, env.scene.rooms):
            assert room.contains(((box[0] + box[2]) / 2, (box[1] + box[3]) / 2)) and name in ROOM_TYPES
        assert "room_boxes" not in ObjectSearchEnv(episodes=[ep], width=32, height=24).observation_space.spaces
    finally:
        env.close()


def test_room_plan_refuses_an_unknown_room_name(tmp_path, episodes):
    ep = episodes.episodes[0]
    scene = json.loads((SCENES_ROOT / ep.scene).read_text())
    scene["rooms"][0]["name"] = "ballroom"
    (tmp_path / "instruct-v2").mkdir()
    (tmp_path / ep.scene).write_text(json.dumps(scene))
    env = ObjectSearchEnv(episodes=[ep], width=32, height=24, room_plan=True, scenes_root=str(tmp_path))
    try:
        with pytest.raises(SimError, match=r"rooms\[0\]\.name 'ballroom': a room plan names rooms by one of kitchen"):
            env.reset(options={"episode": ep})
    finally:
        env.close()


def test_shipped_instruction_data_regenerates_on_its_seed_roles():
    """The split file's roles: the reported episodes on fresh ``evaluation`` seeds, the development
    ones on the ``calibration`` apartments; both files regenerate byte for byte."""
    from scenes.make_calibration_v2 import search_files
    from scenes.make_instruct_v2 import DEV_FILE, EPISODE_FILE, build_files, dev_file
    from scenes.shipped import ROOT
    from sim_envs.scenes.splits import splits

    files = build_files()
    assert all((ROOT / rel).read_text() == text for rel, text in files.items())
    apartments = {rel: text for rel, text in search_files().items() if rel.endswith(".json")}
    assert dev_file(apartments)[DEV_FILE] == (ROOT / DEV_FILE).read_text()
    roles = {rel: {splits().seed_role(e.scene_seed) for e in load_episodes(ROOT / rel).episodes} for rel in (EPISODE_FILE, DEV_FILE)}
    assert roles == {EPISODE_FILE: {"evaluation"}, DEV_FILE: {"calibration"}}
