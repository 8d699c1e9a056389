"""Push geometry golden values, worked out by hand (table plane, z up)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from planners.errors import DegenerateGeometryError
from planners.push import plan_push, side_normal

S2 = math.sqrt(0.5)


def test_object_left_of_line_pushed_right():
    # Line x = 0 running along +y; the viewer faces +y, so its right is +x.
    plan = plan_push(
        [-0.2, 0.5, 0.8], [0.0, 0.0, 0.8], [0.0, 1.0, 0.0], "right",
        view_dir=[0.0, 1.0, 0.0], radius=0.05, margin=0.1, approach_clearance=0.05,
    )  # fmt: skip
    np.testing.assert_allclose(plan.push_direction, [1.0, 0.0, 0.0])
    assert plan.signed_distance == pytest.approx(-0.2)
    assert plan.push_distance == pytest.approx(0.3)  # -0.2 -> +0.1
    assert not plan.already_on_side
    np.testing.assert_allclose(plan.contact_xyz, [-0.25, 0.5, 0.8])
    np.testing.assert_allclose(plan.pre_push_xyz, [-0.30, 0.5, 0.8])
    np.testing.assert_allclose(plan.push_end_xyz, [0.05, 0.5, 0.8])
    np.testing.assert_allclose(plan.object_goal_xyz, [0.1, 0.5, 0.8])


def test_viewer_facing_the_other_way_swaps_sides():
    # Facing -y, the viewer's right is -x: "left" is now +x.
    plan = plan_push([-0.2, 0.5, 0.0], [0.0, 0.0], [0.0, 1.0], "left", view_dir=[0.0, -1.0], radius=0.0, margin=0.0)
    np.testing.assert_allclose(plan.push_direction, [1.0, 0.0, 0.0])
    assert plan.push_distance == pytest.approx(0.2)
    # Flipping the line direction changes nothing.
    flipped = plan_push([-0.2, 0.5, 0.0], [0.0, 0.0], [0.0, -1.0], "left", view_dir=[0.0, -1.0], radius=0.0)
    np.testing.assert_allclose(flipped.push_direction, plan.push_direction)


def test_already_on_the_requested_side():
    plan = plan_push([0.3, 0.0, 0.0], [0.0, 0.0], [0.0, 1.0], "right", view_dir=[0.0, 1.0], radius=0.05, margin=0.1)
    assert plan.already_on_side
    assert plan.signed_distance == pytest.approx(0.3)
    assert plan.push_distance == 0.0
    np.testing.assert_allclose(plan.object_goal_xyz, [0.3, 0.0, 0.0])
    # On the right side but not yet margin past the line: a short push remains.
    near = plan_push([0.04, 0.0, 0.0], [0.0, 0.0], [0.0, 1.0], "right", view_dir=[0.0, 1.0], radius=0.05, margin=0.1)
    assert not near.already_on_side and near.push_distance == pytest.approx(0.06)


def test_diagonal_line():
    # Line through (1, 1) along (1, 1); viewer faces +y (right = +x) -> normal (1, -1)/sqrt 2.
    plan = plan_push(
        [0.0, 1.0, 0.7], [1.0, 1.0, 0.7], [1.0, 1.0, 0.0], "right", view_dir=[0.0, 1.0], radius=0.1, margin=0.1
    )
    np.testing.assert_allclose(plan.push_direction, [S2, -S2, 0.0])
    assert plan.signed_distance == pytest.approx(-S2)  # (-1, 0) . (1, -1)/sqrt 2
    assert plan.push_distance == pytest.approx(S2 + 0.1)
    np.testing.assert_allclose(plan.object_goal_xyz, [(S2 + 0.1) * S2, 1.0 - (S2 + 0.1) * S2, 0.7])
    np.testing.assert_allclose(plan.contact_xyz, [-0.1 * S2, 1.0 + 0.1 * S2, 0.7])
    # The goal lies exactly `margin` past the line.
    goal_signed = (plan.object_goal_xyz[:2] - np.array([1.0, 1.0])) @ plan.push_direction[:2]
    assert goal_signed == pytest.approx(0.1)


def test_footprint_points_set_the_contact():
    # A 0.2 x 0.1 box centred at (-0.2, 0): its rearmost points along +x are 0.1 behind the centre.
    xs, ys = np.meshgrid([-0.3, -0.1], [-0.05, 0.05])
    footprint = np.stack([xs.ravel(), ys.ravel()], axis=1)
    plan = plan_push([-0.2, 0.0, 0.0], [0.0, 0.0], [0.0, 1.0], "right", view_dir=[0.0, 1.0], footprint_xy=footprint)
    np.testing.assert_allclose(plan.contact_xyz, [-0.3, 0.0, 0.0])


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"line_dir": [0.0, 0.0, 1.0]}, DegenerateGeometryError, "no horizontal direction"),
        ({"line_dir": [0.0, 0.0]}, DegenerateGeometryError, "no horizontal direction"),
        ({"view_dir": [1.0, 0.0]}, DegenerateGeometryError, "left-right"),
        ({"view_dir": [0.0, 0.0, -1.0]}, DegenerateGeometryError, "facing direction"),
        ({"object_xyz": [np.nan, 0.0, 0.0]}, ValueError, "finite"),
        ({"line_point": [0.0, np.inf]}, ValueError, "finite"),
        ({"side": "up"}, ValueError, "'left' or 'right'"),
        ({"radius": -0.1}, ValueError, "radius"),
        ({"radius": None}, ValueError, "exactly one"),
    ],
)
def test_push_rejects_bad_input(kwargs, error, match):
    args = {
        "object_xyz": [0.0, 0.0, 0.0],
        "line_point": [1.0, 0.0],
        "line_dir": [0.0, 1.0],
        "side": "right",
        "view_dir": [0.0, 1.0],
        "radius": 0.05,
    }
    args.update(kwargs)
    with pytest.raises(error, match=match):
        plan_push(
            args.pop("object_xyz"), args.pop("line_point"), args.pop("line_dir"), args.pop("side"), **args
        )


def test_side_normal_left_is_opposite_right():
    right = side_normal([1.0, 2.0], [0.3, 1.0], "right")
    left = side_normal([1.0, 2.0], [0.3, 1.0], "left")
    np.testing.assert_allclose(left, -right)
    assert np.linalg.norm(right) == pytest.approx(1.0)
    assert right @ np.array([1.0, 2.0]) == pytest.approx(0.0)
