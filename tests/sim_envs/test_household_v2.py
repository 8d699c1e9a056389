"""Household v2: library-filled apartments, containers, the shipped scenes and search episodes."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import pytest

from harness.runner.suites import DEFAULT_SUITES, get_suite
from harness.runner.tasks import EpisodeJob, run_episode
from sim_envs.assets.library import catalogue, instance_size
from sim_envs.scenes.descriptions import referents
from sim_envs.scenes.episodes import EpisodeFormatError, episodes_text, load_episodes
from sim_envs.scenes.floorplan import occupancy_grid, reachable_rooms
from sim_envs.scenes.format import SceneObject, load_scene, scene_from_json
from sim_envs.scenes.gen_household import generate_household
from sim_envs.scenes.gen_household_v2 import FLOOR_CATEGORIES, generate_household_v2
from sim_envs.scenes.household_format import container_floor
from sim_envs.scenes.search_episodes import room_of
from sim_envs.scenes.search_episodes_v2 import V2_DIR, V2_SEARCH_FILE, apartment_seeds, v2_search_episodes
from sim_envs.scenes.splits import splits

ROOT = Path(__file__).resolve().parents[2]


def test_generation_is_deterministic_and_matches_the_shipped_file():
    seed = apartment_seeds()[0]
    a, b = generate_household_v2(seed), generate_household_v2(seed)
    assert a == b
    assert json.dumps(a.to_json(), indent=1) == (V2_DIR / f"household-v2-{seed}.json").read_text()


def test_v1_apartments_are_unchanged():
    shipped = json.loads((ROOT / "scenes" / "household" / "household-0003.json").read_text())
    assert json.loads(json.dumps(generate_household(3).to_json())) == shipped


def test_shipped_apartments_are_full_valid_and_on_evaluation_seeds():
    files = sorted(V2_DIR.glob("household-v2-*.json"))
    assert len(files) == 20
    lo, hi = splits().seeds["evaluation"]
    for f in files:
        scene = load_scene(f)  # validates supports (1 cm) and overlaps
        assert lo <= scene.seed < hi
        assert len(scene.objects) >= 25 and len({o.category for o in scene.objects}) >= 20
        assert len({o.name for o in scene.objects}) == len(scene.objects)
        supports = {o.support for o in scene.objects}
        assert any(s.startswith("obj") for s in supports)  # something inside a container
        ids = {o.id: o for o in scene.objects}
        for o in scene.objects:
            if o.support in ids:
                assert container_floor(ids[o.support].asset, ids[o.support].size) is not None
            if o.support == "floor":
                assert o.category in FLOOR_CATEGORIES
            else:
                assert o.category not in FLOOR_CATEGORIES
        assert reachable_rooms(scene) == {r.id for r in scene.rooms}


def test_floor_objects_block_the_floor_plan():
    scene = load_scene(V2_DIR / f"household-v2-{apartment_seeds()[0]}.json")
    floor = [o for o in scene.objects if o.support == "floor"]
    assert floor
    occ = occupancy_grid(scene)
    c, r = ((floor[0].position[:2] - occ.origin) // occ.cell).astype(int)
    assert occ.blocked_hw[r, c]
    bare = replace(scene, objects=tuple(o for o in scene.objects if o.support != "floor"))
    assert not occupancy_grid(bare).blocked_hw[r, c]


def test_instances_follow_the_seed_role():
    sp = splits()
    scene = generate_household_v2(sp.seeds["tower_train"][0])
    assert all(sp.instances[o.asset[4:]] == "train" for o in scene.objects)
    with pytest.raises(ValueError, match="expected a seed in a split seed range"):
        generate_household_v2(7)


def test_library_container_floor_supports_what_is_inside():
    bowl = catalogue().instances["bowl-000"]
    size = instance_size(bowl)
    floor = container_floor(bowl.asset, size)
    assert 0 < floor < size[2] / 2
    assert container_floor("lib:mug-000", (0.1, 0.1, 0.1)) is None and container_floor("bowl", (0.16, 0.16, 0.06)) == 0.01
    apple = catalogue().instances["apple-001"]
    b = SceneObject("obj0", "b", "bowl", bowl.asset, bowl.color, (0.0, 0.0, 0.0), 0.0, size, support="floor")

    def doc(z):
        a = SceneObject("obj1", "a", "apple", apple.asset, apple.color, (0.0, 0.0, z), 0.0, (0.07, 0.07, 0.07), support="obj0")
        return {"format": "cf-scene", "version": 2, "id": "t", "objects": [o.__dict__ for o in (b, a)]}

    scene_from_json(doc(round(floor, 4)))
    with pytest.raises(ValueError, match="floats"):
        scene_from_json(doc(size[2]))


def test_shipped_episodes_load_and_name_their_goal_uniquely():
    eps = v2_search_episodes()
    assert V2_SEARCH_FILE.read_text().startswith('{"format": "cf-episodes", "version": 2')
    assert len(eps.episodes) >= 100
    kinds = {e.description_kind for e in eps.episodes}
    assert kinds == {"name", "synonym", "attribute", "function"}
    lo, hi = splits().seeds["evaluation"]
    scenes = {}
    for e in eps.episodes:
        assert lo <= e.scene_seed < hi
        scene = scenes.setdefault(e.scene, load_scene(ROOT / "scenes" / e.scene))
        goal = scene.object(e.goals[0].object_id)
        assert [o.id for o in referents(e.instruction, scene.objects)] == [goal.id]
        assert room_of(scene, e.start_pose[:2]) != room_of(scene, goal.position[:2])


def test_v1_episode_files_stay_version_1_and_bad_kinds_are_refused(tmp_path):
    v1 = ROOT / "scenes" / "household" / "episodes-v1.jsonl"
    assert episodes_text(load_episodes(v1, check_scenes=False)) == v1.read_text()
    lines = V2_SEARCH_FILE.read_text().splitlines()[:2]
    bad = tmp_path / "bad.jsonl"
    bad.write_text(lines[0] + "\n" + lines[1].replace('"description_kind": "name"', '"description_kind": "smell"') + "\n")
    with pytest.raises(EpisodeFormatError, match="description_kind"):
        load_episodes(bad, check_scenes=False)


def test_search_v2_suite_is_the_default_search_and_runs_its_first_16_sealed_episodes():
    from harness.runner.run import RunConfig, episode_jobs
    from sim_envs.scenes.sealed import SEALED_FOLDER

    suite = get_suite("search-v2")
    assert suite.episodes_file == SEALED_FOLDER / "search-episodes-v2.jsonl" and suite.task == "object_search"
    assert "search-v2" in DEFAULT_SUITES and "search" not in DEFAULT_SUITES
    eps = load_episodes(suite.episodes_file).episodes
    jobs = episode_jobs(suite, RunConfig(suites=("search-v2",), agents=("random-walker",)), "t")
    assert [j.episode.episode_id for j in jobs] == [e.episode_id for e in eps[:16]]
    kinds = [e.description_kind for e in eps[:16]]
    assert {k: kinds.count(k) for k in set(kinds)} == {"name": 4, "synonym": 4, "attribute": 4, "function": 4}
    every = episode_jobs(suite, RunConfig(suites=("search-v2",), agents=("random-walker",), limit=150), "t")
    assert len(every) == len(eps) == 150
    # the weak reactive reference runs a shorter slice by default, every episode with --limit
    default = episode_jobs(suite, RunConfig(suites=("search-v2",)), "t")
    counts = {a: sum(j.agent == a for j in default) for a in suite.agents}
    assert counts == {"map-navigator": 16, "twin-navigator": 16, "frame-searcher": 8, "random-walker": 16}


def test_oracle_solves_a_v2_episode():
    ep = v2_search_episodes().episodes[0]
    rec = run_episode(EpisodeJob("t", "search-v2", "object_search", "oracle-searcher", {}, ep, 0, {"width": 32, "height": 24}))
    assert rec["status"] == "ok", rec.get("error")
    assert rec["metrics"]["success"] and rec["metrics"]["spl"] > 0.7
