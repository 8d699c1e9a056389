"""Wall boxes both simulators build, and furniture standing in a wall refused at scene load."""

import json
import math

import pytest

from conceptfusion.errors import SceneFormatError
from sim_envs.scenes.episodes import SCENES_ROOT
from sim_envs.scenes.format import scene_from_json
from sim_envs.scenes.household_format import Furniture, Wall
from sim_envs.scenes.household_shapes import LINTEL_HEIGHT, furniture_in_walls, wall_boxes

V2 = SCENES_ROOT / "household-v2" / "household-v2-300000.json"


def test_a_wall_with_a_door_is_two_spans_and_a_lintel_each_in_two_slabs():
    # a 4 m wall along +x, 0.2 m thick, 2.5 m high, a 1 m door from 1.0 to 2.0 m
    w = Wall("w", (0.0, 0.0), (4.0, 0.0), thickness=0.2, height=2.5, materials=("tile", "carpet"), doors=((1.0, 1.0),))
    boxes = wall_boxes(w)
    assert [b.name for b in boxes] == ["w_0l", "w_0r", "w_1l", "w_1r", "w_2l", "w_2r"]
    left_span, _, right_span, _, lintel, lintel_r = boxes
    assert left_span.centre == pytest.approx((0.5, 0.05, 1.25)) and left_span.half == pytest.approx((0.5, 0.05, 1.25))
    assert right_span.centre == pytest.approx((3.0, 0.05, 1.25)) and right_span.half == pytest.approx((1.0, 0.05, 1.25))
    assert lintel.centre == pytest.approx((1.5, 0.05, (LINTEL_HEIGHT + 2.5) / 2)) and lintel.half[2] == pytest.approx(0.2)
    assert lintel_r.centre[1] == pytest.approx(-0.05)  # the right face's slab is on the other side
    assert (left_span.material, boxes[1].material) == ("tile", "carpet")
    assert all(b.yaw == 0.0 for b in boxes)


def test_furniture_in_walls_measures_how_deep():
    w = Wall("w", (0.0, 0.0), (0.0, 4.0), thickness=0.1)  # along +y: the wall spans x in [-0.05, 0.05]
    clear = Furniture("a", "a", "desk", (0.36, 1.0, 0.0), 0.0, (0.6, 0.4, 0.7), "wood")  # x from 0.06
    inside = Furniture("b", "b", "desk", (0.25, 3.0, 0.0), 0.0, (0.6, 0.4, 0.7), "wood")  # x from -0.05: 0.1 m in
    turned = Furniture("c", "c", "desk", (0.25, 2.0, 0.0), math.pi / 2, (0.6, 0.4, 0.7), "wood")  # x from 0.05: touching
    found = furniture_in_walls([w], [clear, inside, turned])
    assert [(j, wid) for j, wid, _ in found] == [(1, "w")]
    assert found[0][2] == pytest.approx(0.1)


def test_furniture_reaching_into_a_wall_is_refused_at_load():
    doc = json.loads(V2.read_text())
    wall = doc["walls"][0]
    (sx, sy), (ex, ey) = wall["start"], wall["end"]
    f = doc["furniture"][0]
    f["position"] = [(sx + ex) / 2, (sy + ey) / 2, 0.0]  # centred on the wall's middle
    with pytest.raises(SceneFormatError, match=rf"x\.json: furniture\[0\] \('{f['id']}', {f['name']}\): its footprint reaches "
                                                rf"0\.\d+ m into wall '{wall['id']}'; expected at most 0\.01 m"):
        scene_from_json(doc, source="x.json")
