"""A map cut to some of its points (``subset``) and thinned on a voxel grid (``thin_map``)."""

import numpy as np
import pytest

from conceptfusion.cameras import intrinsics_from_fovy
from conceptfusion.map.fusion import PointFusionMap
from conceptfusion.map.thin import thin_map, voxel_representatives
from conceptfusion.perception.features import PixelFeatures
from conceptfusion.synthetic import Box, look_at, orbit_poses, render_boxes

H, W = 48, 64
K = intrinsics_from_fovy(60.0, W, H)
SCENE = [
    Box("floor", (0.0, 0.0, -0.05), (4.0, 4.0, 0.1), (150, 150, 150)),
    Box("red", (0.2, 0.1, 0.1), (0.2, 0.2, 0.2), (200, 30, 30)),
    Box("blue", (-0.3, -0.2, 0.15), (0.2, 0.3, 0.3), (30, 30, 200)),
]


def _map() -> PointFusionMap:
    """Three labelled boxes seen from an orbit, a different feature per box and per frame."""
    rng = np.random.default_rng(0)
    fmap = PointFusionMap(8)
    for t, pose in enumerate(orbit_poses((0.0, 0.0, 0.0), 1.2, 1.0, 6, sweep_deg=90.0)):
        f = render_boxes(SCENE, K, pose, H, W)
        palette = rng.standard_normal((len(SCENE) + 1, 8)).astype(np.float32)
        fmap.integrate(f.rgb, f.depth, K, pose, PixelFeatures(palette, (f.segmentation + 1).astype(np.int32)))
    return fmap


def test_a_subset_keeps_each_point_exactly_and_drops_unused_bank_rows():
    fmap = _map()
    keep = np.arange(0, len(fmap), 7)
    sub = fmap.subset(keep)
    assert len(sub) == len(keep)
    assert np.array_equal(sub.points, fmap.points[keep]) and np.array_equal(sub.colors, fmap.colors[keep])
    assert np.array_equal(sub.confidence, fmap.confidence[keep])
    q = np.random.default_rng(1).standard_normal(8).astype(np.float32)
    # the same mixtures; the bank's matrix-vector product may round differently for a shorter bank
    np.testing.assert_allclose(sub.scores(q), fmap.scores(q)[keep], rtol=0, atol=1e-6)
    assert np.array_equal(sub.features(), fmap.features(keep))
    one = fmap.subset([3])
    assert len(one._store.bank) <= fmap.config.slots < len(fmap._store.bank)  # only the rows point 3 uses
    with pytest.raises(IndexError, match="expected values in"):
        fmap.subset([len(fmap)])
    with pytest.raises(ValueError, match="distinct"):
        fmap.subset([1, 1])


def test_voxel_representatives_keep_the_most_confident_point_of_each_cell():
    pts = np.array([[0.01, 0.01, 0.0], [0.02, 0.03, 0.0], [0.5, 0.5, 0.5], [0.09, 0.0, 0.0]])  # grid from (0.01, 0, 0)
    conf = np.array([1.0, 3.0, 0.5, 2.0])
    assert voxel_representatives(pts, conf, 0.05).tolist() == [1, 2, 3]
    assert voxel_representatives(pts - 0.3, conf, 1.0).tolist() == [1]  # a cloud around the origin: one cell still
    assert voxel_representatives(pts, conf, 1.0).tolist() == [1]
    assert voxel_representatives(pts, np.ones(4), 1.0).tolist() == [0]  # ties: the lowest index
    with pytest.raises(ValueError, match="positive edge"):
        voxel_representatives(pts, conf, 0.0)
    with pytest.raises(ValueError, match="same N"):
        voxel_representatives(pts, conf[:2], 0.1)


def test_thinning_fits_the_budget_on_the_finest_grid_that_does():
    fmap = _map()
    same = thin_map(fmap, len(fmap))
    assert same.map is fmap and same.voxel == 0.0
    budget = len(fmap) // 5
    thinned = thin_map(fmap, budget, base_voxel=0.01)
    assert 0 < len(thinned.map) <= budget and thinned.original_points == len(fmap)
    finer = voxel_representatives(fmap.points, fmap.confidence, thinned.voxel / 2**0.5)
    assert len(finer) > budget  # the next finer grid would not have fitted
    # every kept point is an original point with its own score, and each box is still there
    kept = voxel_representatives(fmap.points, fmap.confidence, thinned.voxel)
    q = np.random.default_rng(2).standard_normal(8).astype(np.float32)
    np.testing.assert_allclose(thinned.map.scores(q), fmap.scores(q)[kept], rtol=0, atol=1e-6)
    for box in SCENE[1:]:
        inside = np.all(np.abs(thinned.map.points - np.array(box.center)) <= np.array(box.size) / 2 + 0.01, axis=1)
        assert inside.sum() >= 3
    with pytest.raises(ValueError, match="at least 1"):
        thin_map(fmap, 0)
