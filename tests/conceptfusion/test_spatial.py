"""3D spatial comparators on hand-built boxes with hand-worked answers."""

import math

import numpy as np
import pytest

from conceptfusion.map.regions import Region, region_from_points
from conceptfusion.spatial.comparators import (
    COMPARATOR_NAMES,
    COMPARATORS,
    SpatialAnswer,
    can_fit_inside,
    closest_distance,
    get_comparator,
    how_far,
    is_bigger,
    is_contained,
    is_to_the_left,
    is_to_the_right,
    on_top_of,
    oriented_extents,
    robust_bounds,
    under,
)

# Viewer looks along +x with z up: +y is the viewer's left, -y the right.
LOOK_X = (1.0, 0.0, 0.0)


def box(lo, hi, n=6, yaw_deg=0.0) -> Region:
    """A solid grid of n^3 points filling the box [lo, hi], optionally turned about z."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    axes = [np.linspace(lo[i], hi[i], n) for i in range(3)]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    if yaw_deg:
        c = (lo + hi) / 2
        t = math.radians(yaw_deg)
        rot = np.array([[math.cos(t), -math.sin(t), 0], [math.sin(t), math.cos(t), 0], [0, 0, 1]])
        pts = (pts - c) @ rot.T + c
    return region_from_points(pts)


TABLE = box((0, 0, 0), (1, 1, 0.75))
MUG = box((0.4, 0.4, 0.75), (0.5, 0.5, 0.87))  # resting on the table
FLOATING_MUG = box((0.4, 0.4, 0.95), (0.5, 0.5, 1.07))  # 0.2 m above it


# -- answers for missing objects ---------------------------------------------------------------


@pytest.mark.parametrize("name", COMPARATOR_NAMES)
def test_none_argument_is_an_explicit_not_found(name):
    fn = COMPARATORS[name]
    kw = {"viewing_direction": LOOK_X} if name in ("isToTheLeft", "isToTheRight") else {}
    ans = fn(None, TABLE, names=("red mug", "table"), **kw)
    assert isinstance(ans, SpatialAnswer)
    assert ans.value is None and not ans.found and not ans.found_a and ans.found_b
    assert ans.relation == name
    assert "'red mug' was not found" in ans.reason and "table" not in ans.reason
    both = fn(None, None, **kw)
    assert both.value is None and not both.found_a and not both.found_b
    assert "'object1' and 'object2' were not found" in both.reason
    second = fn(MUG, None, **kw)
    assert second.found_a and not second.found_b and "'object2' was not found" in second.reason


def test_bad_arguments_raise_clear_errors():
    with pytest.raises(TypeError, match="region_a: expected a Region or None, got ndarray"):
        how_far(np.zeros((3, 3)), TABLE)
    empty = Region(points_n3=np.zeros((0, 3)), scores_n=np.zeros(0, np.float32))
    with pytest.raises(ValueError, match="region_b: region has no points; pass None"):
        how_far(TABLE, empty)
    nan = Region(points_n3=np.array([[0.0, np.nan, 0.0]]), scores_n=np.ones(1, np.float32))
    with pytest.raises(ValueError, match="NaN or inf"):
        on_top_of(nan, TABLE)
    with pytest.raises(ValueError, match="trim_pct"):
        is_contained(MUG, TABLE, trim_pct=60)
    with pytest.raises(ValueError, match="center: expected 'centroid' or 'median'"):
        how_far(MUG, TABLE, center="middle")
    with pytest.raises(ValueError, match="measure"):
        is_bigger(MUG, TABLE, measure="weight")
    with pytest.raises(ValueError, match="min_overlap"):
        on_top_of(MUG, TABLE, min_overlap=0.0)
    with pytest.raises(ValueError, match="clearance"):
        can_fit_inside(MUG, TABLE, clearance=-0.1)
    with pytest.raises(TypeError, match="names"):
        how_far(MUG, TABLE, names=("mug",))


# -- howFar ------------------------------------------------------------------------------------


def test_how_far_is_the_centroid_distance_and_reports_closest_surfaces():
    a = box((0, 0, 0), (1, 1, 1))  # centre (0.5, 0.5, 0.5)
    b = box((3, 4, 0), (4, 5, 1))  # centre (3.5, 4.5, 0.5): 3-4-5 triangle
    ans = how_far(a, b)
    assert ans.found and ans.value == pytest.approx(5.0)
    assert ans.detail("centre") == pytest.approx(5.0)
    # closest corners (1, 1, z) and (3, 4, z): sqrt(4 + 9)
    assert ans.detail("closest") == pytest.approx(math.sqrt(13.0))
    assert closest_distance(a, b).value == pytest.approx(math.sqrt(13.0))
    assert how_far(b, a).value == pytest.approx(5.0)  # symmetric
    assert "5.00 m" in ans.reason
    with pytest.raises(KeyError, match="available"):
        ans.detail("nope")


def test_how_far_touching_boxes_have_zero_closest_distance():
    a = box((0, 0, 0), (1, 1, 1))
    b = box((1, 0, 0), (2, 1, 1))
    ans = how_far(a, b)
    assert ans.value == pytest.approx(1.0)
    assert ans.detail("closest") == pytest.approx(0.0)


def test_how_far_median_ignores_a_stray_point():
    pts = np.concatenate([box((0, 0, 0), (1, 1, 1), n=5).points_n3, [[100.0, 0.5, 0.5]]])
    a = region_from_points(pts)
    b = box((2, 0, 0), (3, 1, 1), n=5)
    # mean x of a is (125 * 0.5 + 100) / 126 = 1.2897 -> centroid distance 2.5 - 1.2897
    assert how_far(a, b).value == pytest.approx(2.5 - (125 * 0.5 + 100) / 126)
    assert how_far(a, b, center="median").value == pytest.approx(2.0)


# -- left / right ------------------------------------------------------------------------------


def test_left_right_with_a_viewing_direction():
    left_box = box((0, 1, 0), (0.2, 1.2, 0.2))  # +y: viewer's left when looking along +x
    right_box = box((0, -1.2, 0), (0.2, -1, 0.2))
    assert is_to_the_left(left_box, right_box, viewing_direction=LOOK_X).value is True
    assert is_to_the_right(left_box, right_box, viewing_direction=LOOK_X).value is False
    assert is_to_the_right(right_box, left_box, viewing_direction=LOOK_X).value is True
    # 2.2 m apart along y
    assert is_to_the_left(left_box, right_box, viewing_direction=LOOK_X).detail("offset") == pytest.approx(2.2)
    # turning round swaps the answer
    look_back = (-1.0, 0.0, 0.0)
    assert is_to_the_left(left_box, right_box, viewing_direction=look_back).value is False
    assert is_to_the_right(left_box, right_box, viewing_direction=look_back).value is True
    # a tilted camera (looking down at 45 degrees) sees the same left/right
    assert is_to_the_left(left_box, right_box, viewing_direction=(1.0, 0.0, -1.0)).value is True


def test_left_right_with_a_viewer_position():
    a = box((2, 0.5, 0), (2.2, 0.7, 0.2))
    b = box((2, -0.7, 0), (2.2, -0.5, 0.2))
    # at the origin looking towards +x: a (+y) is on the left
    assert is_to_the_left(a, b, viewer_position=(0, 0, 1.5)).value is True
    # from the far side (x = 4, looking towards -x) it is on the right
    assert is_to_the_right(a, b, viewer_position=(4, 0, 1.5)).value is True
    # directly above: undecided, not a guess
    above = is_to_the_left(a, b, viewer_position=(2.1, 0.0, 3.0))
    assert above.value is None and "directly above" in above.reason


def test_left_right_in_line_objects_are_neither():
    a = box((0, 0, 0), (0.2, 0.2, 0.2))
    b = box((1, 0, 0), (1.2, 0.2, 0.2))  # straight ahead, behind a
    assert is_to_the_left(a, b, viewing_direction=LOOK_X).value is False
    assert is_to_the_right(a, b, viewing_direction=LOOK_X).value is False


def test_left_right_needs_exactly_one_viewpoint_and_a_horizontal_one():
    with pytest.raises(ValueError, match="exactly one of viewing_direction or viewer_position"):
        is_to_the_left(MUG, TABLE)
    with pytest.raises(ValueError, match="exactly one"):
        is_to_the_right(MUG, TABLE, viewing_direction=LOOK_X, viewer_position=(0, 0, 0))
    with pytest.raises(ValueError, match="vertical"):
        is_to_the_left(MUG, TABLE, viewing_direction=(0, 0, -1))
    with pytest.raises(ValueError, match="viewing_direction: expected 3 finite numbers"):
        is_to_the_left(MUG, TABLE, viewing_direction=(1, 0))


# -- support -----------------------------------------------------------------------------------


def test_on_top_of_and_under_for_a_resting_mug():
    ans = on_top_of(MUG, TABLE)
    assert ans.value is True and ans.detail("gap") == pytest.approx(0.0)
    assert ans.detail("overlap") == pytest.approx(1.0)
    assert on_top_of(TABLE, MUG).value is False
    assert under(TABLE, MUG).value is True
    assert under(MUG, TABLE).value is False


def test_floating_box_is_not_on_top_without_contact():
    ans = on_top_of(FLOATING_MUG, TABLE)
    assert ans.value is False and ans.detail("gap") == pytest.approx(0.2)
    assert "floats 0.200 m above" in ans.reason
    assert under(TABLE, FLOATING_MUG).value is False
    # when contact is not required, "above with overlapping footprints" is enough
    assert on_top_of(FLOATING_MUG, TABLE, require_contact=False).value is True
    assert under(TABLE, FLOATING_MUG, require_contact=False).value is True
    # a small gap inside the contact tolerance still counts as resting
    hovering = box((0.4, 0.4, 0.77), (0.5, 0.5, 0.89))
    assert on_top_of(hovering, TABLE, contact_tol=0.03).value is True
    assert on_top_of(hovering, TABLE, contact_tol=0.01).value is False


def test_side_by_side_touching_boxes_do_not_support_each_other():
    a = box((0, 0, 0), (1, 1, 1))
    b = box((1, 0, 0), (2, 1, 1))
    assert on_top_of(a, b).value is False
    assert under(a, b).value is False


def test_on_top_needs_footprint_overlap():
    beside = box((1.5, 0.0, 0.75), (1.6, 0.1, 0.85))  # at table-top height but off the table
    ans = on_top_of(beside, TABLE)
    assert ans.value is False and ans.detail("overlap") == pytest.approx(0.0)
    # overhanging by half: overlap fraction 0.5 passes the default 0.3, fails 0.6
    half = box((0.95, 0.4, 0.75), (1.05, 0.5, 0.85))
    assert on_top_of(half, TABLE).detail("overlap") == pytest.approx(0.5)
    assert on_top_of(half, TABLE).value is True
    assert on_top_of(half, TABLE, min_overlap=0.6).value is False


def test_a_flat_sheet_on_a_table_is_on_top():
    # a sheet of paper seen as one plane at the table-top height (zero thickness)
    xs, ys = np.meshgrid(np.linspace(0.2, 0.5, 4), np.linspace(0.2, 0.4, 4))
    sheet = region_from_points(np.stack([xs.ravel(), ys.ravel(), np.full(16, 0.751)], axis=1))
    assert on_top_of(sheet, TABLE).value is True


# -- size --------------------------------------------------------------------------------------


def test_is_bigger_volume_and_equal_sizes():
    big = box((0, 0, 0), (1, 1, 1))
    small = box((2, 0, 0), (2.5, 0.5, 0.5))
    ans = is_bigger(big, small)
    assert ans.value is True
    assert ans.detail("size_a") == pytest.approx(1.0) and ans.detail("size_b") == pytest.approx(0.125)
    assert is_bigger(small, big).value is False
    twin = box((5, 5, 5), (6, 6, 6))
    same = is_bigger(big, twin)
    assert same.value is False and "about the same size" in same.reason
    assert is_bigger(twin, big).value is False
    # longest side: a 2 m pole beats the 1 m cube by length, not by volume
    pole = box((0, 0, 0), (0.05, 0.05, 2.0))
    assert is_bigger(pole, big, measure="max_extent").value is True
    assert is_bigger(pole, big).value is False


def test_is_bigger_does_not_count_rotation_as_size():
    flat = box((0, 0, 0), (1.0, 0.2, 0.1))
    turned = box((0, 0, 0), (1.0, 0.2, 0.1), yaw_deg=45)  # world box ~0.85 x 0.85
    assert np.sort(oriented_extents(turned.points_n3)) == pytest.approx([0.1, 0.2, 1.0], abs=1e-6)
    assert is_bigger(turned, flat).value is False
    assert is_bigger(flat, turned).value is False


def test_can_fit_inside_with_clearance_and_rotation():
    crate = box((0, 0, 0), (0.6, 0.4, 0.3))
    brick = box((0, 0, 0), (0.2, 0.1, 0.05))
    assert can_fit_inside(brick, crate).value is True
    assert can_fit_inside(crate, brick).value is False
    # a standing bottle 0.35 m tall: too tall upright, fits lying down (sorted extents)
    bottle = box((1, 1, 0), (1.08, 1.08, 0.35))
    assert can_fit_inside(bottle, crate).value is True
    assert can_fit_inside(bottle, crate, allow_rotation=False).value is False
    # equal sizes: no room for the clearance
    twin = box((3, 3, 0), (3.6, 3.4, 0.3))
    assert can_fit_inside(twin, crate).detail("margin") == pytest.approx(-0.01)
    assert can_fit_inside(twin, crate).value is False
    assert can_fit_inside(twin, crate, clearance=0.0).value is True


def test_can_fit_inside_sees_through_a_yaw_rotation():
    # a 0.55 m long rod turned 45 degrees: its world box is ~0.42 x 0.42, but it fits the
    # 0.6 m crate lengthways
    rod = box((0, 0, 0), (0.55, 0.05, 0.05), yaw_deg=45)
    crate = box((2, 0, 0), (2.6, 0.3, 0.3))
    assert can_fit_inside(rod, crate).value is True
    # turned crate, straight rod: same answer
    crate_turned = box((2, 0, 0), (2.6, 0.3, 0.3), yaw_deg=30)
    straight = box((0, 0, 0), (0.55, 0.05, 0.05))
    assert can_fit_inside(straight, crate_turned).value is True
    too_long = box((0, 0, 0), (0.7, 0.05, 0.05), yaw_deg=45)
    assert can_fit_inside(too_long, crate).value is False


# -- containment -------------------------------------------------------------------------------


def test_is_contained_nested_touching_and_equal_boxes():
    bowl = box((0, 0, 0), (0.3, 0.3, 0.1))
    bread = box((0.1, 0.1, 0.01), (0.2, 0.2, 0.08))
    assert is_contained(bread, bowl).value is True
    assert is_contained(bowl, bread).value is False
    ans = is_contained(bread, bowl)
    assert ans.detail("inside_fraction") == pytest.approx(1.0)
    assert ans.detail("protrusion") == pytest.approx(-0.01)
    # equal boxes: a box is contained in a copy of itself
    assert is_contained(bowl, box((0, 0, 0), (0.3, 0.3, 0.1))).value is True
    # touching side by side: not contained
    neighbour = box((0.3, 0, 0), (0.6, 0.3, 0.1))
    assert is_contained(neighbour, bowl).value is False


def test_is_contained_tolerance_and_open_top():
    bowl = box((0, 0, 0), (0.3, 0.3, 0.1))
    loaf = box((0.05, 0.05, 0.01), (0.25, 0.25, 0.16))  # sticks 0.06 m out of the top
    ans = is_contained(loaf, bowl)
    assert ans.value is False and ans.detail("protrusion") == pytest.approx(0.06)
    assert "sticks out" in ans.reason
    assert is_contained(loaf, bowl, tol=0.07).value is True
    assert is_contained(loaf, bowl, open_top=True).value is True
    # open top does not excuse sticking out of a side
    sideways = box((0.25, 0.05, 0.01), (0.45, 0.25, 0.05))
    assert is_contained(sideways, bowl, open_top=True).value is False


# -- robust statistics -------------------------------------------------------------------------


def test_robust_bounds_ignore_stray_points():
    pts = box((0, 0, 0), (1, 1, 1), n=10).points_n3  # 1000 points
    noisy = np.concatenate([pts, [[5.0, 5.0, 5.0]]])
    lo, hi = robust_bounds(noisy, trim_pct=1.0)
    assert lo == pytest.approx([0, 0, 0]) and hi == pytest.approx([1, 1, 1])
    lo0, hi0 = robust_bounds(noisy, trim_pct=0.0)
    assert hi0 == pytest.approx([5, 5, 5])
    # the stray point does not stop the cube from resting on a table below it
    cube = region_from_points(noisy + [0, 0, 1.0])
    slab = box((-1, -1, 0), (2, 2, 1.0))
    assert on_top_of(cube, slab).value is True
    assert on_top_of(cube, slab, trim_pct=0.0).value is True  # bottom is not affected
    assert is_contained(region_from_points(noisy), box((-0.1, -0.1, -0.1), (1.1, 1.1, 1.1))).value is True
    assert is_contained(region_from_points(noisy), box((-0.1, -0.1, -0.1), (1.1, 1.1, 1.1)), trim_pct=0).value is False


def test_single_point_and_collinear_regions_are_handled():
    dot = region_from_points([[0.5, 0.5, 0.8]])
    assert on_top_of(dot, TABLE, contact_tol=0.06).value is True
    line = region_from_points([[0, 0, 0], [1, 0, 0], [2, 0, 0]])
    assert oriented_extents(line.points_n3) == pytest.approx([2.0, 0.0, 0.0])
    assert can_fit_inside(dot, TABLE).value is True


# -- lookup table ------------------------------------------------------------------------------


def test_lookup_table_has_the_eight_paper_names():
    assert COMPARATOR_NAMES == (
        "howFar", "isToTheRight", "isToTheLeft", "isContained", "onTopOf", "under", "isBigger", "canFitInside",
    )
    assert get_comparator("howFar") is how_far
    assert get_comparator("howfar") is how_far  # the paper's figure writes it in lower case
    assert get_comparator("onTopOf")(MUG, TABLE).value is True


def test_unknown_comparator_names_suggest_the_nearest():
    with pytest.raises(ValueError, match=r"unknown spatial comparator 'isToTheRigt'; did you mean 'isToTheRight'"):
        get_comparator("isToTheRigt")
    with pytest.raises(ValueError, match=r"valid: howFar, isToTheRight"):
        get_comparator("teleport")
    with pytest.raises(TypeError, match="name: expected a str"):
        get_comparator(3)
