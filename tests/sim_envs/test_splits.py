"""The split file: every category, instance and seed has one role, and no role leaks into another."""

import json

import pytest

from sim_envs.assets.library import catalogue
from sim_envs.scenes.splits import (
    SPLITS_FILE, V1_FLOOR_CALIBRATION_SCENES, V1_FLOOR_VALIDATION_SCENES, SplitError, derive_splits, load_splits, splits,
)


def test_the_shipped_file_is_the_derivation_and_loads():
    assert json.loads(SPLITS_FILE.read_text()) == derive_splits()
    s = splits()
    assert len(s.categories_of("test")) >= 12
    assert s.categories_of("val") and s.instances_of("val")


def test_every_category_and_instance_has_exactly_one_role():
    cat, s = catalogue(), splits()
    assert set(s.categories) == set(cat.categories)
    assert set(s.instances) == set(cat.instances)
    for name, role in s.categories.items():
        roles = [s.instances[i.id] for i in cat.instances_of(name)]
        if role != "train":  # a held-out category is held out whole
            assert set(roles) == {role}, name
        elif len(roles) >= 3:  # one held-out instance and one validation instance per seen category
            assert roles.count("test") == 1 and roles.count("val") == 1, name


def test_no_held_out_asset_is_trained_on():
    cat, s = catalogue(), splits()
    train = set(s.instances_of("train"))
    for iid in train:
        assert s.categories[cat.instances[iid].category] == "train", iid
    held_out_cats = set(s.categories_of("test")) | set(s.categories_of("val"))
    assert not {cat.instances[i].category for i in train} & held_out_cats


def test_every_held_out_category_keeps_a_seen_parent():
    cat, s = catalogue(), splits()
    seen_ancestors = {a for c in s.categories_of("train") for a in cat.ancestors(c)}
    for name in s.categories_of("test"):
        parents = [a for a in cat.ancestors(name) if a != "object"]
        assert set(parents) & seen_ancestors, f"{name}: no seen parent among {parents}"


def test_seed_ranges_are_disjoint_and_roles_found():
    s = splits()
    ranges = sorted(s.seeds.values())
    assert all(a[1] <= b[0] for a, b in zip(ranges, ranges[1:]))
    for role, (lo, hi) in s.seeds.items():
        assert s.seed_role(lo) == role and s.seed_role(hi - 1) == role
    assert s.seed_role(0) is None
    assert s.seeds_of("evaluation", 3) == [s.seeds["evaluation"][0] + k for k in range(3)]
    with pytest.raises(SplitError, match="asked for"):
        s.seeds_of("calibration", 10**9)


def test_reserved_scenes_are_the_v1_floor_scenes():
    s = splits()
    assert s.reserved_scene_ids("calibration") == sorted(V1_FLOOR_CALIBRATION_SCENES)
    assert s.reserved_scene_ids("validation") == sorted(V1_FLOOR_VALIDATION_SCENES)
    assert s.reserved_scene_ids() == sorted(V1_FLOOR_CALIBRATION_SCENES + V1_FLOOR_VALIDATION_SCENES)
    assert not set(V1_FLOOR_CALIBRATION_SCENES) & set(V1_FLOOR_VALIDATION_SCENES)
    assert s.is_reserved_scene("tabletop-0111") and s.is_reserved_scene("tabletop/tabletop-8559.json")
    assert not s.is_reserved_scene("tabletop-0129") and not s.is_reserved_scene("tabletop/tabletop-0129.json")
    assert not s.is_reserved_scene("calibration/tabletop-0111.json")  # another folder: not the shipped scene
    with pytest.raises(SplitError, match="reserved role 'test': expected one of calibration, validation"):
        s.reserved_scene_ids("test")


def _write(tmp_path, data):
    path = tmp_path / "splits.json"
    path.write_text(json.dumps(data))
    return path


def test_a_file_that_overlaps_itself_is_refused(tmp_path):
    data = derive_splits()
    held = next(i for i, r in data["instances"].items() if data["categories"][catalogue().instances[i].category] == "test")
    bad = json.loads(json.dumps(data))
    bad["instances"][held] = "train"
    with pytest.raises(SplitError, match=rf"instances\.{held}: category .* is 'test'.*got 'train'"):
        load_splits(_write(tmp_path, bad))
    bad = json.loads(json.dumps(data))
    bad["seeds"]["calibration"] = [140_000, 201_000]
    with pytest.raises(SplitError, match=r"seeds\.calibration .* overlap"):
        load_splits(_write(tmp_path, bad))


@pytest.mark.parametrize("edit, match", [
    (lambda d: d["categories"].update(mug="holdout"), r"categories\.mug: expected one of train, val, test"),
    (lambda d: d["instances"].update({"mug-999": "train"}), r"instances\.mug-999: not an instance"),
    (lambda d: d["categories"].pop("mug"), r"category 'mug' has no role"),
    (lambda d: d["seeds"].update(evaluation=[5, 1]), r"seeds\.evaluation: expected \[start, stop\)"),
    (lambda d: d.update(version=2), "expected format 'cf-splits' version 1"),
    (lambda d: d.update(instances={}), "instances: expected a non-empty object"),
    (lambda d: d["reserved_scenes"].update({"tabletop-0129": "train"}),
     r"reserved_scenes\.tabletop-0129: expected one of calibration, validation, got 'train'"),
    (lambda d: d["reserved_scenes"].update({"tabletop-9999": "calibration"}),
     r"splits\.json: reserved_scenes\.tabletop-9999: not a shipped scene"),
    (lambda d: d["reserved_scenes"].update({"kitchen-0001": "validation"}),
     r"reserved_scenes\.kitchen-0001: not a shipped scene"),
    (lambda d: d.pop("reserved_scenes"), r"reserved_scenes: expected an object of shipped scene id -> role"),
])
def test_malformed_files_name_the_field(tmp_path, edit, match):
    data = derive_splits()
    edit(data)
    with pytest.raises(SplitError, match=match):
        load_splits(_write(tmp_path, data))


def test_missing_and_non_json_files(tmp_path):
    with pytest.raises(SplitError, match="no such split file"):
        load_splits(tmp_path / "nope.json")
    (tmp_path / "bin.json").write_bytes(b"\x00\xff\x10")
    with pytest.raises(SplitError, match=r"bin\.json:line 1: not a split file: not UTF-8 text \(byte 0xff at offset 1\)"):
        load_splits(tmp_path / "bin.json")
    (tmp_path / "text.json").write_text("{not json")
    with pytest.raises(SplitError, match="not a JSON split file"):
        load_splits(tmp_path / "text.json")
    assert issubclass(SplitError, ValueError)
