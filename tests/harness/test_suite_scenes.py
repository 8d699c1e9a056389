"""No evaluation suite runs on a scene that trained or calibrated anything (the split file's rule)."""

from __future__ import annotations

from pathlib import Path

import pytest

from harness.maps.suites import MAP_SUITES, scene_ids
from harness.runner.bounds import calibration_suite, regression_suites
from harness.runner.map_jobs import map_suite_jobs
from harness.runner.run import RunConfig, episode_jobs
from harness.runner.suites import GATE_FOLDER, HEADLINE_GATE, SUITES, get_suite, suite_episodes
from sim_envs.scenes.episodes import SCENES_ROOT, load_episodes
from sim_envs.scenes.splits import splits
from tower_training.score_floor import FloorConfig

RESERVED = frozenset(splits().reserved_scene_ids())
FLOOR_CALIBRATION = frozenset(p.stem for p in (SCENES_ROOT / "calibration").glob("*.json") if "episodes" not in p.stem)
"""Scene ids of the regression bounds' calibration episodes (``scenes/calibration/``)."""


def _suite_scenes(name: str) -> list[tuple[str, int | None]]:
    """(scene id, scene seed or None) of every job of suite ``name`` at default options."""
    suite = get_suite(name)
    config = RunConfig(suites=(name,))
    if suite.kind == "maps":  # v2 scene ids end in their generator seed
        return [(j.scene_id, int(j.scene_id.rpartition("-")[2]) if "-v2-" in j.scene_id else None)
                for j in map_suite_jobs(name, config, "r")]
    return [(Path(j.episode.scene).stem, j.episode.scene_seed) for j in episode_jobs(suite, config, "r")]


def test_the_reserved_scenes_are_the_v1_tower_floor_scenes():
    cfg = FloorConfig()
    assert set(cfg.calibration_scenes) | set(cfg.validation_scenes) == RESERVED and len(RESERVED) == 12
    assert set(splits().reserved_scene_ids("calibration")) == set(cfg.calibration_scenes)
    assert FLOOR_CALIBRATION and len(FLOOR_CALIBRATION) == 150 + 20


@pytest.mark.parametrize("name", sorted(SUITES))
def test_no_evaluation_suite_uses_a_reserved_or_calibration_scene(name):
    scenes = _suite_scenes(name)
    assert scenes, name
    ids = {sid for sid, _ in scenes}
    assert not ids & RESERVED, f"{name}: reserved scenes {sorted(ids & RESERVED)}"
    assert not ids & FLOOR_CALIBRATION, f"{name}: floor calibration scenes {sorted(ids & FLOOR_CALIBRATION)}"
    # v2 scenes come from evaluation seeds only (the agent suites from the sealed test set's);
    # v1 seeds (0-9999) lie outside every seed range
    roles = {splits().seed_role(seed) for _, seed in scenes if seed is not None}
    # the gate's episodes (the headline suites and the search gate's PyBullet slice) are a development tool:
    # tower_val seeds, no test instance (test_gate_data)
    if get_suite(name).episodes_file is not None and get_suite(name).episodes_file.parent == GATE_FOLDER:
        assert name in HEADLINE_GATE or name == "regression-search-v2-pybullet", name
        assert roles == {"tower_val"}, f"{name}: scene seeds of roles {roles}"
        return
    assert roles <= {None, "evaluation", "sealed"}, f"{name}: scene seeds of roles {roles}"
    if name in ("search-v2", "rearrange-v2"):
        assert roles == {"sealed"}, f"{name}: scene seeds of roles {roles}"


def test_map_suites_are_all_covered_and_take_the_first_unreserved_scenes():
    assert set(MAP_SUITES) <= set(SUITES)
    shipped = sorted(p.stem for p in (SCENES_ROOT / "tabletop").glob("tabletop-*.json"))
    assert shipped[0] in RESERVED  # the first shipped scene calibrated the v1 floor
    assert scene_ids("tabletop", None) == [s for s in shipped if s not in RESERVED][:6]
    assert [j.scene_id for j in map_suite_jobs("query", RunConfig(suites=("query",)), "r")] == scene_ids("tabletop", None)


def test_episode_suites_skip_reserved_episodes_and_keep_their_counts():
    rearrange = get_suite("rearrange")
    shipped = load_episodes(rearrange.episodes_file).episodes
    on_reserved = [i for i, e in enumerate(shipped) if Path(e.scene).stem in RESERVED]
    assert on_reserved == [3, 9, 21, 27, 28, 29, 30, 36, 37, 39, 44, 45]
    kept = suite_episodes(rearrange)
    assert [e.episode_id for e in kept] == [e.episode_id for i, e in enumerate(shipped) if i not in on_reserved]
    for suite in regression_suites():  # the same rule; the pinned counts are the first N kept episodes
        jobs = episode_jobs(suite, RunConfig(suites=(suite.name,)), "r")
        for agent in suite.agents:
            mine = [j.episode.episode_id for j in jobs if j.agent == agent]
            assert mine == [e.episode_id for e in suite_episodes(suite)[:suite.agent_limits.get(agent, suite.limit)]]
            assert len(mine) == suite.agent_limits.get(agent, suite.limit)
        # the bounds' own calibration episodes are all kept
        cal = calibration_suite(suite)
        assert len(suite_episodes(cal)) == len(load_episodes(suite.calibration_file).episodes)
    with pytest.raises(ValueError, match="suite 'query' has no episodes file"):
        suite_episodes(get_suite("query"))



def test_the_default_comparison_is_the_v2_world():
    from harness.runner.suites import DEFAULT_SUITES

    assert set(DEFAULT_SUITES) == {"query-open", "query-v2", "ablation-v2", "spatial-v2", "rearrange-v2", "search-v2", "chain-v2"}
    for name in DEFAULT_SUITES:
        scenes = _suite_scenes(name)
        assert scenes and all("-v2-" in sid for sid, _ in scenes), name
        # the map suites on evaluation seeds, the agent suites on the sealed test set
        want = "sealed" if get_suite(name).kind == "episodes" else "evaluation"
        assert {splits().seed_role(seed) for _, seed in scenes} == {want}, name


def test_v2_calibration_search_data_regenerates_and_stays_out_of_every_suite():
    from scenes.make_calibration_v2 import FOLDER, NUM_APARTMENTS, SEARCH_FILE, search_files
    from scenes.shipped import ROOT
    from sim_envs.scenes.search_episodes_v2 import PER_SCENE
    from tower_training.room_floor import RoomFloorConfig, room_floor_seeds

    files = search_files()
    assert len(files) == 1 + NUM_APARTMENTS == 31 and all((ROOT / rel).read_text() == text for rel, text in files.items())
    eps = load_episodes(ROOT / SEARCH_FILE).episodes
    assert len(eps) == NUM_APARTMENTS * PER_SCENE == 180 and {splits().seed_role(e.scene_seed) for e in eps} == {"calibration"}
    cal_scenes = {Path(rel).stem for rel in files if rel.endswith(".json")}
    room_floor = {f"household-v2-{s}" for s in room_floor_seeds(RoomFloorConfig())}
    assert not cal_scenes & room_floor  # apart from the apartments that chose the score floor
    for name in SUITES:
        assert not {sid for sid, _ in _suite_scenes(name)} & cal_scenes, name
    assert all(e.scene.startswith(f"{FOLDER}/") for e in eps)


def test_v2_calibration_tables_regenerate_and_stay_out_of_every_suite_and_floor():
    from scenes.make_calibration_v2 import FOLDER, NUM_TABLE_EPISODES, REARRANGE_FILE, table_files
    from scenes.shipped import ROOT
    from tower_training.room_floor import RoomFloorConfig, room_floor_seeds
    from tower_training.score_floor import FloorConfigV2

    eps = load_episodes(ROOT / REARRANGE_FILE).episodes
    assert len(eps) == NUM_TABLE_EPISODES and {splits().seed_role(e.scene_seed) for e in eps} == {"calibration"}
    assert all(e.scene.startswith(f"{FOLDER}/") and (ROOT / e.scene).is_file() for e in eps)
    # the first episode and its table regenerate exactly (the generator draws them in order)
    head = table_files(1)
    lines = (ROOT / REARRANGE_FILE).read_text().splitlines()
    assert head.pop(REARRANGE_FILE).splitlines() == lines[:2]
    assert len(head) == 1 and all((ROOT / rel).read_text() == text for rel, text in head.items())
    tables = {Path(e.scene).stem for e in eps}
    # apart from the seeds the tower's table and apartment score floors are calibrated on
    floor_seeds = set(splits().seeds_of("calibration", FloorConfigV2().scenes)) | set(room_floor_seeds(RoomFloorConfig()))
    assert not {e.scene_seed for e in eps} & floor_seeds
    for name in SUITES:
        assert not {sid for sid, _ in _suite_scenes(name)} & tables, name


def test_v2_validation_tables_name_only_validation_objects_regenerate_and_stay_out_of_every_suite():
    from scenes.make_validation_v2 import FOLDER, NUM_TABLE_EPISODES, REARRANGE_FILE, table_files
    from scenes.shipped import ROOT
    from sim_envs.scenes.format import load_scene
    from sim_envs.scenes.splits import object_group
    from tower_training.world_v2 import DataConfigV2

    eps = load_episodes(ROOT / REARRANGE_FILE).episodes
    assert len(eps) == NUM_TABLE_EPISODES and {splits().seed_role(e.scene_seed) for e in eps} == {"tower_val"}
    groups = set()
    for e in eps:
        objects = {o.id: o for o in load_scene(ROOT / e.scene).objects}
        groups |= {object_group(objects[g.object_id]) for g in e.goals}
        # the tables hold no test instance
        assert {object_group(o) for o in objects.values()} <= {"seen", "validation"}, e.episode_id
    assert groups == {"validation"}
    head = table_files(1)
    assert head.pop(REARRANGE_FILE).splitlines() == (ROOT / REARRANGE_FILE).read_text().splitlines()[:2]
    assert len(head) == 1 and all((ROOT / rel).read_text() == text for rel, text in head.items())
    # apart from the tower's own validation arrangements, and from every suite
    assert not {e.scene_seed for e in eps} & set(DataConfigV2().seeds("val", splits()))
    tables = {Path(e.scene).stem for e in eps}
    assert all(e.scene.startswith(f"{FOLDER}/") for e in eps)
    for name in SUITES:
        assert not {sid for sid, _ in _suite_scenes(name)} & tables, name


def test_a_goal_group_that_is_not_a_split_group_is_refused():
    from sim_envs.scenes.tabletop_v2_episodes import generate_tabletop_v2_episodes

    with pytest.raises(ValueError, match="goal_groups: \\['unseen'\\] are not split groups"):
        generate_tabletop_v2_episodes(0, 1, [300000], goal_groups=("unseen",))


def test_v2_validation_apartments_name_only_validation_goals_regenerate_and_stay_out_of_every_suite():
    from scenes.make_validation_v2 import FOLDER, NUM_APARTMENTS, SEARCH_FILE, search_files
    from scenes.shipped import ROOT
    from sim_envs.assets.library import is_library_asset
    from sim_envs.scenes.format import load_scene
    from sim_envs.scenes.splits import object_group

    files = search_files()
    assert len(files) == 1 + NUM_APARTMENTS and all((ROOT / rel).read_text() == text for rel, text in files.items())
    eps = load_episodes(ROOT / SEARCH_FILE).episodes
    assert len(eps) >= 5 * NUM_APARTMENTS and {splits().seed_role(e.scene_seed) for e in eps} == {"tower_val"}
    for e in eps:
        objects = {o.id: o for o in load_scene(ROOT / e.scene).objects}
        assert object_group(objects[e.goals[0].object_id]) == "validation", e.episode_id
        assert {object_group(o) for o in objects.values() if is_library_asset(o.asset)} <= {"seen", "validation"}, e.episode_id
    apartments = {Path(rel).stem for rel in files if rel.endswith(".json")}
    assert all(e.scene.startswith(f"{FOLDER}/") for e in eps)
    for name in SUITES:
        assert not {sid for sid, _ in _suite_scenes(name)} & apartments, name


def test_a_search_goal_group_that_is_not_a_split_group_is_refused():
    from sim_envs.scenes.search_episodes import generate_search_episodes

    with pytest.raises(ValueError, match="goal_groups: \\['test'\\] are not split groups"):
        generate_search_episodes([], goal_groups=("test",))
