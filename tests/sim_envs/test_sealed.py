"""The sealed test set: pinned by its manifest, unread by every development command."""

import json
import shutil

import pytest

from harness.runner import bounds, develop
from harness.runner.suites import get_suite, suite_episodes
from sim_envs.scenes import sealed
from sim_envs.scenes.episodes import SCENES_ROOT, load_episodes, resolve_scene
from sim_envs.scenes.sealed import SEALED_FOLDER, SealedSetError, refuse_sealed, verify_sealed
from sim_envs.scenes.splits import object_group, splits

SEARCH = SEALED_FOLDER / "search-episodes-v2.jsonl"
REARRANGE = SEALED_FOLDER / "rearrange-episodes-v2.jsonl"


def _scenes(path):
    return {e.scene for e in load_episodes(path).episodes}


def test_shipped_sealed_set_matches_its_manifest_and_sizes():
    for path, n in ((SEARCH, 150), (REARRANGE, 160)):
        verify_sealed(path, _scenes(path))
        assert len(load_episodes(path).episodes) == n


def test_sealed_scenes_hold_no_validation_instance_and_lie_on_sealed_seeds():
    groups = set()
    for path in (SEARCH, REARRANGE):
        for ep in load_episodes(path).episodes:
            assert splits().seed_role(ep.scene_seed) == "sealed"
            scene = resolve_scene(ep.scene, ep.scene_seed)
            lib = [o for o in scene.objects if str(o.asset).startswith("lib:")]
            assert lib and all(object_group(o) != "validation" for o in lib), ep.episode_id
            by_id = {o.id: o for o in scene.objects}
            groups |= {object_group(by_id[g.object_id]) for g in ep.goals}
    assert groups == {"seen", "held_out_instance", "held_out_category"}


def test_the_v2_agent_suites_run_the_sealed_set():
    for name, path in (("search-v2", SEARCH), ("rearrange-v2", REARRANGE)):
        suite = get_suite(name)
        assert suite.episodes_file == path
        assert [e.episode_id for e in suite_episodes(suite)] == [e.episode_id for e in load_episodes(path).episodes]


@pytest.fixture
def tampered(tmp_path, monkeypatch):
    """A copy of the scenes folder's sealed set (episodes, manifest, two tables) to change."""
    root = tmp_path / "scenes"
    folder = root / SEALED_FOLDER.name
    folder.mkdir(parents=True)
    for name in (REARRANGE.name, sealed.MANIFEST_NAME):
        shutil.copy(SEALED_FOLDER / name, folder / name)
    for scene in sorted(_scenes(REARRANGE))[:2]:
        shutil.copy(SCENES_ROOT / scene, root / scene)
    monkeypatch.setattr(sealed, "SCENES_ROOT", root)
    monkeypatch.setattr(sealed, "SEALED_FOLDER", folder)
    return folder / REARRANGE.name


def _rewrite_line(path, no, change):
    lines = path.read_text().splitlines()
    rec = json.loads(lines[no - 1])
    change(rec)
    lines[no - 1] = json.dumps(rec)
    path.write_text("\n".join(lines) + "\n")


def test_a_changed_field_is_refused_naming_file_line_and_field(tampered):
    verify_sealed(tampered)
    _rewrite_line(tampered, 5, lambda r: r.update(instruction="push the red mug to the left of the line"))
    with pytest.raises(SealedSetError, match=r"rearrange-episodes-v2.jsonl:line 5: field 'instruction' differs from its recorded hash"):
        verify_sealed(tampered)


def test_added_removed_and_reordered_lines_are_refused(tampered):
    text = tampered.read_text()
    lines = text.splitlines()
    tampered.write_text(text + lines[-1] + "\n")
    with pytest.raises(SealedSetError, match=r"line 162: a line the manifest does not record"):
        verify_sealed(tampered)
    tampered.write_text("\n".join(lines[:-1]) + "\n")
    with pytest.raises(SealedSetError, match=r"line 161: missing \(the manifest records 161 lines\)"):
        verify_sealed(tampered)
    lines[1], lines[2] = lines[2], lines[1]
    tampered.write_text("\n".join(lines) + "\n")
    with pytest.raises(SealedSetError, match=r"line 2: field '[a-z_]+' differs"):
        verify_sealed(tampered)


def test_a_changed_scene_is_refused_naming_the_field(tampered):
    scene = sorted(_scenes(REARRANGE))[0]
    path = sealed.SCENES_ROOT / scene
    data = json.loads(path.read_text())
    data["objects"][0]["position"][0] += 0.01
    path.write_text(json.dumps(data))
    with pytest.raises(SealedSetError, match=rf"{scene}: field 'objects' differs from its recorded hash"):
        verify_sealed(tampered, [scene])


def test_a_missing_or_foreign_manifest_is_refused(tampered):
    manifest = tampered.parent / sealed.MANIFEST_NAME
    manifest.write_text(json.dumps({"format": "something else"}))
    with pytest.raises(SealedSetError, match="expected format 'cf-sealed-manifest' version 1"):
        verify_sealed(tampered)
    manifest.unlink()
    with pytest.raises(SealedSetError, match="has no manifest"):
        verify_sealed(tampered)


def test_refuse_sealed_knows_sealed_files_episodes_and_seeds(tmp_path):
    refuse_sealed(SCENES_ROOT / "calibration-v2" / "search-episodes-v2.jsonl", "test")
    refuse_sealed(load_episodes(SCENES_ROOT / "calibration-v2" / "search-episodes-v2.jsonl").episodes, "test")
    refuse_sealed([200_000, 300_000], "test")
    with pytest.raises(SealedSetError, match="my-command: refusing to read the sealed test set"):
        refuse_sealed(SEARCH, "my-command")
    with pytest.raises(SealedSetError, match="scene seed 400003"):
        refuse_sealed([200_000, 400_003], "my-command")
    # a copy of the sealed episodes elsewhere is still sealed: its episodes lie on sealed seeds
    copy = tmp_path / "copy.jsonl"
    shutil.copy(SEARCH, copy)
    with pytest.raises(SealedSetError, match="episode 'search-v2-sealed-0000'"):
        refuse_sealed(load_episodes(copy).episodes, "my-command")


def test_development_runs_refuse_the_sealed_set(monkeypatch, tmp_path):
    copy = tmp_path / "copy.jsonl"
    shutil.copy(SEARCH, copy)
    for target in ("sealed-v2/search-episodes-v2.jsonl", str(copy)):
        monkeypatch.setitem(develop.DEVELOPMENT_EPISODES["search-v2"], "calibration", target)
        with pytest.raises(SealedSetError, match="python -m harness.runner.develop: refusing to read the sealed test set"):
            develop.development_suite("search-v2")
    # the first evaluation episodes are a development set now
    assert develop.development_suite("search-v2", episodes="dev2").episodes_file == SCENES_ROOT / "household-v2" / "episodes-v2.jsonl"


def test_floor_calibration_refuses_the_sealed_set():
    import dataclasses

    suite = dataclasses.replace(get_suite("regression-search"), calibration_file=SEARCH)
    with pytest.raises(SealedSetError, match="cfharness develop bounds"):
        bounds.calibration_suite(suite)


def test_map_suite_development_scripts_refuse_sealed_scenes():
    from harness.maps.query_open_develop import calibration_queries
    from harness.maps.spatial_develop import answer_calibration_scene

    scene = str(SCENES_ROOT / sorted(_scenes(REARRANGE))[0])
    with pytest.raises(SealedSetError, match="query_open_develop"):
        calibration_queries((scene, "color", 2, 64, 48, True))
    with pytest.raises(SealedSetError, match="spatial_develop"):
        answer_calibration_scene((scene, "3d", "color", True))


def test_tower_training_refuses_sealed_seeds():
    from tower_training.room_floor import RoomFloorConfig, room_floor_seeds
    from tower_training.world_v2 import RoomDataConfig

    with pytest.raises(SealedSetError, match="tower_training"):
        RoomDataConfig(scenes=3, seed0=400_000, role="sealed").scene_seeds(splits())
    assert all(splits().seed_role(s) == "calibration" for s in room_floor_seeds(RoomFloorConfig()))
