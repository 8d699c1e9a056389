"""Queries: relative scores, calibrated relevancy, regions, click queries, absent objects."""

import numpy as np
import pytest

from conceptfusion.cameras import intrinsics_from_fovy
from conceptfusion.perception.encoders import ColorNameEncoder
from conceptfusion.map.fusion import PointFusionMap
from conceptfusion.perception.pipeline import frame_features
from conceptfusion.map.query import (
    NEGATIVE_PHRASES,
    click_query_vector,
    connected_regions,
    locate,
    relative_scores,
    relevancy,
)
from conceptfusion.synthetic import orbit_poses, render_boxes, tabletop_boxes

H, W = 96, 128
K = intrinsics_from_fovy(60.0, W, H)
BOXES = tabletop_boxes()


@pytest.fixture(scope="module")
def scene():
    enc = ColorNameEncoder()
    fmap = PointFusionMap(enc.dim)
    for pose in orbit_poses((0.0, 0.0, 0.45), 1.3, 0.8, 8):
        f = render_boxes(BOXES, K, pose, H, W)
        masks = np.stack([f.segmentation == i for i in range(len(BOXES)) if np.any(f.segmentation == i)])
        fmap.integrate(f.rgb, f.depth, K, pose, frame_features(f.rgb, masks, enc))
    return enc, fmap, enc.encode_text(list(NEGATIVE_PHRASES))


def test_relative_scores_min_max():
    s = relative_scores(np.array([-1.0, 0.0, 1.0, np.nan]))
    assert s[:3] == pytest.approx([0.0, 0.5, 1.0])
    assert np.isnan(s[3])
    assert relative_scores(np.array([0.3, 0.3])) == pytest.approx([1.0, 1.0])


def test_relevancy_uses_the_hardest_negative():
    s = np.array([0.5, 0.2])
    neg = np.array([[0.1, 0.1], [0.3, 0.4]])
    # point 0: margin 10 * (0.3 - 0.5) = -2 -> 1 / (1 + e^-2) = 0.88080
    # point 1: margin 10 * (0.4 - 0.2) = 2 -> 0.11920
    assert relevancy(s, neg) == pytest.approx([0.88080, 0.11920], abs=1e-4)
    with pytest.raises(ValueError, match="negative_scores_kn"):
        relevancy(s, np.zeros((2, 3)))


def test_connected_regions_split_two_clusters():
    rng = np.random.default_rng(0)
    a = rng.uniform(0, 0.1, (50, 3))
    b = rng.uniform(0, 0.1, (30, 3)) + [1.0, 0.0, 0.0]
    pts = np.concatenate([a, b])
    scores = np.concatenate([np.full(50, 0.5), np.full(30, 0.9)])
    regions = connected_regions(pts, np.ones(80, bool), scores, voxel_size=0.05, min_points=10)
    assert [r.num_points for r in regions] == [30, 50]  # best score first
    assert regions[0].centroid[0] > 0.9
    assert connected_regions(pts, np.zeros(80, bool), scores) == []
    assert connected_regions(pts, np.ones(80, bool), scores, voxel_size=0.05, min_points=40)[0].num_points == 50


def test_text_query_finds_the_right_object(scene):
    enc, fmap, neg = scene
    for name in ("red", "blue", "yellow"):
        box = next(b for b in BOXES if b.name == f"{name} box")
        result = locate(fmap, enc.encode_text([name])[0], neg)
        assert result.found, result.reason
        assert np.linalg.norm(result.best.median - np.asarray(box.center)) < 0.06
        inside = np.all(np.abs(result.best.points_n3 - box.center) <= np.asarray(box.size) / 2 + 0.02, axis=1)
        assert inside.mean() > 0.9


def test_absent_object_is_not_found_but_paper_threshold_finds_something(scene):
    enc, fmap, neg = scene
    q = enc.encode_text(["pink"])[0]
    result = locate(fmap, q, neg)
    assert not result.found and result.best is None
    assert "generic phrases" in result.reason
    # the paper's relative threshold alone always selects something
    assert np.nanmax(result.relative_n) == pytest.approx(1.0)
    assert (result.relative_n >= 0.6).sum() > 0


def test_click_query_returns_the_fused_feature(scene):
    enc, fmap, neg = scene
    box = next(b for b in BOXES if b.name == "green box")
    top = (box.center[0], box.center[1], box.center[2] + box.size[2] / 2)
    q = click_query_vector(fmap, top)
    assert np.linalg.norm(q) == pytest.approx(1.0, abs=1e-5)
    result = locate(fmap, q, neg)
    assert result.found
    assert np.linalg.norm(result.best.median - np.asarray(box.center)) < 0.06
    with pytest.raises(ValueError, match="max_distance"):
        click_query_vector(fmap, (5.0, 5.0, 5.0))


def test_empty_and_wrong_queries(scene):
    enc, fmap, neg = scene
    with pytest.raises(ValueError, match="non-empty query"):
        enc.encode_text(["  "])
    with pytest.raises(ValueError, match=r"query_d: expected shape \(32,\)"):
        fmap.scores(np.ones(5))
    empty = PointFusionMap(enc.dim)
    result = locate(empty, enc.encode_text(["red"])[0], neg)
    assert not result.found and "no points" in result.reason
