"""Regions lose the surface they stand on (``drop_support``), and only that surface."""

import numpy as np
import pytest

from conceptfusion.errors import DtypeError, ShapeError

from conceptfusion.map.query import locate
from conceptfusion.map.regions import SupportTest, drop_support

TABLE_Z = 0.75


def _grid(x0, x1, y0, y1, z, step=0.01):
    xs, ys = np.meshgrid(np.arange(x0, x1, step), np.arange(y0, y1, step), indexing="ij")
    return np.stack([xs.ravel(), ys.ravel(), np.full(xs.size, z)], axis=1)


def _box(cx, cy, half, height, step=0.01):
    """Top and four sides of a box standing on the table: points and normals."""
    top = _grid(cx - half, cx + half, cy - half, cy + half, TABLE_Z + height, step)
    pts, nrm = [top], [np.tile([0.0, 0.0, 1.0], (len(top), 1))]
    zs = np.arange(TABLE_Z + step, TABLE_Z + height, step)
    along = np.arange(-half, half, step)
    for axis, sign in ((0, 1), (0, -1), (1, 1), (1, -1)):
        a, z = np.meshgrid(along, zs, indexing="ij")
        side = np.zeros((a.size, 3))
        side[:, axis] = (cx, cy)[axis] + sign * half
        side[:, 1 - axis] = (cy, cx)[axis] + a.ravel()
        side[:, 2] = z.ravel()
        n = np.zeros(3)
        n[axis] = sign
        pts.append(side)
        nrm.append(np.tile(n, (len(side), 1)))
    return np.concatenate(pts), np.concatenate(nrm)


@pytest.fixture(scope="module")
def world():
    """A 1 m table top with a 10 cm box (5 cm tall), a 16 cm plate (1.5 cm tall) and a 5 mm thick
    tablet (8 x 12 cm) on it."""
    table = _grid(-0.5, 0.5, -0.5, 0.5, TABLE_Z)
    box_p, box_n = _box(0.2, 0.0, 0.05, 0.05)
    plate = _grid(-0.28, -0.12, -0.08, 0.08, TABLE_Z + 0.015)
    tablet = _grid(-0.04, 0.04, 0.25, 0.37, TABLE_Z + 0.005)
    pts = np.concatenate([table, box_p, plate, tablet])
    flat = len(table) + len(plate) + len(tablet)
    nrm = np.concatenate([np.tile([0.0, 0.0, 1.0], (len(table), 1)), box_n, np.tile([0.0, 0.0, 1.0], (flat - len(table), 1))])
    kind = np.concatenate([np.zeros(len(table), int), np.ones(len(box_p), int), np.full(len(plate), 2), np.full(len(tablet), 3)])
    return pts, nrm, kind


def _near(pts, kind, label, margin):
    """The object's points and the table points within ``margin`` of its footprint (a rim)."""
    obj = pts[kind == label]
    lo, hi = obj[:, :2].min(axis=0) - margin, obj[:, :2].max(axis=0) + margin
    rim = (kind == 0) & np.all((pts[:, :2] >= lo) & (pts[:, :2] <= hi), axis=1)
    return np.flatnonzero((kind == label) | rim)


def test_a_region_that_bled_into_the_table_loses_the_rim_and_keeps_the_object(world):
    pts, nrm, kind = world
    up = nrm[:, 2] >= SupportTest().up_cos
    for label in (1, 2, 3):  # the box, the plate 1.5 cm above the table, the tablet 5 mm above it
        region = _near(pts, kind, label, 0.04)
        assert np.any(kind[region] == 0)
        kept, z0 = drop_support(pts, up, region)
        assert z0 == pytest.approx(TABLE_Z, abs=1e-6)
        assert set(kept.tolist()) == set(np.flatnonzero(kind == label).tolist())
        assert np.all(np.diff(np.searchsorted(region, kept)) > 0)  # a subset, in the region's order


def test_a_region_on_no_surface_or_its_own_top_only_is_left_whole(world):
    pts, nrm, kind = world
    up = nrm[:, 2] >= SupportTest().up_cos
    for label in (1, 3):  # a top is a level, but nothing outside it is at that height (the
        obj = np.flatnonzero(kind == label)  # table is 5 mm under the tablet: not the same surface)
        kept, z0 = drop_support(pts, up, obj)
        assert z0 is None and np.array_equal(kept, obj)
    # the same rim with the table beyond it gone (a box on a pedestal the size of the rim)
    region = _near(pts, kind, 1, 0.04)
    only = np.zeros(len(pts), bool)
    only[region] = True
    kept, z0 = drop_support(pts[only], up[only], np.arange(only.sum()))
    assert z0 is None and len(kept) == only.sum()
    kept, z0 = drop_support(pts, up, np.zeros(0, np.int64))
    assert z0 is None and kept.size == 0


def test_locate_answers_without_the_table_and_says_so_when_only_table_was_selected(world):
    pts, nrm, kind = world

    class Map:
        feature_dim = 2
        points, normals = pts, nrm

        def __len__(self):
            return len(pts)

        def scores(self, q):  # the query scores the box and a rim of table round it
            s = np.full(len(pts), -0.5, np.float32)
            s[_near(pts, kind, 1, 0.04)] = 0.9
            if q[0] < 0:  # the second query scores only a patch of table
                s[:] = -0.5
                s[(kind == 0) & (np.abs(pts[:, 0] + 0.4) < 0.05) & (np.abs(pts[:, 1]) < 0.05)] = 0.9
            return s

    neg = np.array([[0.0, 1.0]], np.float32)
    res = locate(Map(), np.array([1.0, 0.0]), neg, relevancy_threshold=0.0)
    assert res.found and set(res.best.indices_n.tolist()) == set(np.flatnonzero(kind == 1).tolist())
    whole = locate(Map(), np.array([1.0, 0.0]), neg, relevancy_threshold=0.0, support=None)
    assert whole.best.num_points > res.best.num_points and np.any(kind[whole.best.indices_n] == 0)
    table = locate(Map(), np.array([-1.0, 0.0]), neg, relevancy_threshold=0.0)
    assert not table.found and "lay on the surface under them" in table.reason


@pytest.mark.parametrize("field, value, match", [
    ("cell", 0.0, "positive size"), ("level_bin", -0.002, "positive size"), ("tol", -1e-3, "height >= 0"),
    ("above", float("nan"), "height >= 0"), ("ring", 0, "whole number"), ("ring", 2.5, "whole number"),
    ("min_share", 0.0, r"share in \(0, 1\]"), ("ring_cover", 1.5, r"share in \(0, 1\]"), ("up_cos", 1.2, r"\[-1, 1\]"),
])
def test_bad_settings_are_refused_naming_the_field(field, value, match):
    with pytest.raises(ValueError, match=rf"SupportTest\.{field}: expected .*{match}"):
        SupportTest(**{field: value})


def test_bad_inputs_say_what_was_expected(world):
    pts, nrm, kind = world
    up = nrm[:, 2] >= 0.9
    region = np.flatnonzero(kind == 1)
    with pytest.raises(ShapeError, match=r"points_n3: expected shape \(\*, 3\)"):
        drop_support(pts[:, :2], up, region)
    with pytest.raises(ShapeError, match=r"up_n: expected shape"):
        drop_support(pts, up[:-1], region)
    with pytest.raises(DtypeError, match="up_n"):
        drop_support(pts, nrm[:, 2], region)
    with pytest.raises(DtypeError, match="region_idx"):
        drop_support(pts, up, region.astype(float))
    with pytest.raises(IndexError, match=r"region_idx: expected map point indices in \[0, "):
        drop_support(pts, up, np.array([0, len(pts)]))
    kept, z0 = drop_support(pts, up, [])
    assert kept.dtype == np.int64 and kept.size == 0 and z0 is None
