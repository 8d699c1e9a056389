"""Household scenes: format round trip, validation errors, generator invariants, reachability."""

import copy
import json
import math

import numpy as np
import pytest

from sim_envs.scenes.floorplan import occupancy_grid, reachable_rooms
from sim_envs.assets.furniture import FURNITURE, MATERIALS, materials_xml
from sim_envs.scenes.format import Scene, load_scene, save_scene, scene_from_json
from sim_envs.scenes.gen_tabletop import generate_tabletop
from sim_envs.scenes.gen_household import generate_household


@pytest.fixture(scope="module")
def house():
    return generate_household(0)


def _load(doc):
    return scene_from_json(copy.deepcopy(doc), source="test")


def test_round_trip_and_version(house, tmp_path):
    path = save_scene(house, tmp_path / "h.json")
    doc = json.loads(path.read_text())
    assert doc["version"] == 2 and {"rooms", "walls", "furniture"} <= set(doc)
    assert load_scene(path) == house
    # tabletop scenes are still written as version 1, without household fields, and a v1 file loads
    tab = generate_tabletop(2).to_json()
    assert tab["version"] == 1 and "rooms" not in tab and all("support" not in o for o in tab["objects"])
    assert _load(tab) == generate_tabletop(2)
    newer = dict(tab, version=3)
    with pytest.raises(ValueError, match="version <= 2, got 3"):
        _load(newer)


def test_validation_errors_name_the_ids(house):
    doc = json.loads(json.dumps(house.to_json()))
    furn = doc["furniture"][0]
    bad = copy.deepcopy(doc)
    bad["furniture"][0]["category"] = "spaceship"
    with pytest.raises(ValueError, match=rf"\({furn['id']!r}\): unknown furniture kind 'spaceship'"):
        _load(bad)
    bad = copy.deepcopy(doc)
    bad["furniture"][0]["material"] = "gold"
    with pytest.raises(ValueError, match="unknown material 'gold'"):
        _load(bad)
    obj = doc["objects"][5]
    bad = copy.deepcopy(doc)
    bad["objects"][5]["support"] = "f999"
    with pytest.raises(ValueError, match=rf"object {obj['id']!r} .*support 'f999' is missing"):
        _load(bad)
    bad = copy.deepcopy(doc)
    bad["objects"][5]["position"][2] += 0.05
    with pytest.raises(ValueError, match=rf"object {obj['id']!r} .*floats: base at z="):
        _load(bad)
    bad = copy.deepcopy(doc)
    bad["objects"][5]["position"][0] += 20.0
    with pytest.raises(ValueError, match=rf"object {obj['id']!r} .*floats: its centre .* is off"):
        _load(bad)
    bad = copy.deepcopy(doc)
    bad["walls"][0]["doors"] = [[0.5, 100.0]]
    with pytest.raises(ValueError, match=r"walls\[0\]: door \[0.5, 100.0\] must .* lie within the wall"):
        _load(bad)
    bad = copy.deepcopy(doc)
    bad["rooms"][1]["id"] = bad["rooms"][0]["id"]
    with pytest.raises(ValueError, match="duplicate id 'room0'"):
        _load(bad)
    bad = copy.deepcopy(doc)
    bad["rooms"][0]["floor"] = [[1, 1], [0, 0]]
    with pytest.raises(ValueError, match=r"rooms\[0\].floor: expected lower corner below upper corner"):
        _load(bad)


def test_overlap_on_a_support_is_an_error_but_different_supports_are_fine(house):
    doc = json.loads(json.dumps(house.to_json()))
    by_support = {}
    for i, o in enumerate(doc["objects"]):
        by_support.setdefault((o["support"], round(o["position"][2], 3)), []).append(i)
    i, j = next(v for v in by_support.values() if len(v) >= 2)[:2]
    bad = copy.deepcopy(doc)
    bad["objects"][j]["position"] = list(bad["objects"][i]["position"])
    with pytest.raises(ValueError, match=rf"objects {doc['objects'][i]['id']!r} .* and {doc['objects'][j]['id']!r} .* overlap on"):
        _load(bad)
    # something inside a bowl overlaps the bowl's footprint: allowed (different supports)
    inner = [o for o in house.objects if o.support and o.support.startswith("obj")]
    assert inner and all(house.object(o.support).asset == "bowl" for o in inner)


@pytest.mark.parametrize("seed", [0, 3, 7, 11])
def test_generator_invariants(seed):
    s = generate_household(seed)
    assert len(s.rooms) >= 3 and {"kitchen", "living room", "study"} <= {r.name for r in s.rooms}
    assert len(s.objects) >= 20
    assert len({o.name for o in s.objects}) == len(s.objects)
    assert len({f.name for f in s.furniture}) == len(s.furniture)
    for r in s.rooms:
        pieces = [f for f in s.furniture if r.contains(f.position[:2])]
        assert 2 <= len(pieces) <= 5, (r.name, [f.category for f in pieces])
    doors = [d for w in s.walls for d in w.doors]
    assert len(doors) >= len(s.rooms) - 1 and all(width >= 0.9 for _, width in doors)
    # furniture footprints do not overlap one another and stay inside the walls
    for a in range(len(s.furniture)):
        la, ha = s.furniture[a].footprint()
        room = s.room_at(s.furniture[a].position[:2])
        assert room is not None and room.contains(la, 1e-3) and room.contains(ha, 1e-3)
        for b in range(a + 1, len(s.furniture)):
            lb, hb = s.furniture[b].footprint()
            assert not np.all(np.minimum(ha, hb) - np.maximum(la, lb) > 1e-6), (s.furniture[a].id, s.furniture[b].id)
    # objects on furniture tops, on shelf levels and inside open containers
    kinds = set()
    for o in s.objects:
        if o.support.startswith("obj"):
            kinds.add("in bowl")
            continue
        f = s.piece(o.support)
        local = f.to_local(o.position[:2])
        kinds.add(next(srf.kind for srf in f.surfaces() if srf.contains(local, 0.01) and abs(srf.z - o.position[2]) < 0.01))
    assert "top" in kinds and "in bowl" in kinds
    assert reachable_rooms(s) == {r.id for r in s.rooms}
    for r in s.rooms:
        assert r.floor_material in MATERIALS and r.wall_material in MATERIALS


def test_generator_covers_shelves_containers_and_bedrooms():
    scenes = [generate_household(seed) for seed in range(10)]
    surface_kinds = set()
    for s in scenes:
        for o in s.objects:
            if not o.support.startswith("obj"):
                f = s.piece(o.support)
                local = f.to_local(o.position[:2])
                surface_kinds |= {srf.kind for srf in f.surfaces() if srf.contains(local, 0.01) and abs(srf.z - o.position[2]) < 0.01}
    assert {"top", "shelf", "inside"} <= surface_kinds
    assert any(len(s.rooms) == 4 and "bedroom" in {r.name for r in s.rooms} for s in scenes)
    assert len({json.dumps(s.to_json()) for s in scenes}) == 10


def test_same_seed_same_json():
    assert json.dumps(generate_household(4).to_json()) == json.dumps(generate_household(4).to_json())


def test_reachability_sees_a_closed_door(house):
    # no door in the walls: only the start room is reachable
    closed = Scene(house.id, house.kind, house.seed, None, (), None, {}, house.rooms,
                   tuple(type(w)(w.id, w.start, w.end, w.thickness, w.height, w.materials, ()) for w in house.walls), ())
    assert reachable_rooms(closed) == {house.rooms[0].id}
    # a door narrower than the disc's diameter blocks it too
    narrow = Scene(house.id, house.kind, house.seed, None, (), None, {}, house.rooms,
                   tuple(type(w)(w.id, w.start, w.end, w.thickness, w.height, w.materials, tuple((o, 0.4) for o, _ in w.doors)) for w in house.walls), ())
    assert reachable_rooms(narrow) == {house.rooms[0].id}
    occ = occupancy_grid(house, cell=0.1)
    x, y = occ.centres()
    f = house.furniture[0]
    i, j = np.unravel_index(np.argmin((x - f.position[0]) ** 2 + (y - f.position[1]) ** 2), x.shape)
    assert occ.blocked_hw[i, j]  # under a piece of furniture
    with pytest.raises(ValueError, match="needs rooms"):
        occupancy_grid(generate_tabletop(0))


def test_furniture_kinds_have_surfaces_and_geoms():
    assert {"counter", "dining table", "shelf", "bookshelf", "sofa", "bed", "desk", "cabinet", "coffee table", "chair"} <= set(FURNITURE)
    xml = materials_xml()
    assert xml.count("<texture") == len(MATERIALS) and 'builtin="none"' not in xml
    for name, kind in FURNITURE.items():
        shelves = kind.default_shelves(kind.default_size[2])
        surfaces = kind.surfaces(kind.default_size, shelves)
        assert surfaces and all(0 < s.z <= kind.default_size[2] + 1e-9 for s in surfaces), name
        w, d, _ = kind.default_size
        for s in surfaces:  # inside the footprint and not empty
            assert -w / 2 <= s.lo[0] < s.hi[0] <= w / 2 and -d / 2 <= s.lo[1] < s.hi[1] <= d / 2, name
        assert kind.geoms(kind.default_size, kind.default_material, shelves).count("<geom") >= 1
    assert len(FURNITURE["bookshelf"].surfaces((0.9, 0.35, 1.8), FURNITURE["bookshelf"].default_shelves(1.8))) == 6
    assert any(s.kind == "inside" for s in FURNITURE["basket"].surfaces((0.4, 0.3, 0.2), ()))
    assert any(s.kind == "inside" for s in FURNITURE["cabinet"].surfaces((0.8, 0.45, 0.9), (0.08, 0.45)))


def test_furniture_frames(house):
    for f in house.furniture:
        p = np.array([0.3, -0.2])
        assert np.allclose(f.to_local(f.to_world(p)), p)
        assert math.isclose(abs(math.remainder(f.yaw, math.pi / 2)), 0.0, abs_tol=1e-9)
