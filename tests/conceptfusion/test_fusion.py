"""PointFusion map: geometry recovery, merging rules (eqs. 1-2) and bad input."""

import numpy as np
import pytest

from conceptfusion.cameras import intrinsics_from_fovy
from conceptfusion.errors import DtypeError, PoseError, ShapeError
from conceptfusion.perception.features import PixelFeatures
from conceptfusion.map.fusion import PointFusionMap
from conceptfusion.synthetic import Box, look_at, orbit_poses, render_boxes

H, W = 48, 64
K = intrinsics_from_fovy(60.0, W, H)
FLOOR = [Box("floor", (0.0, 0.0, -0.05), (40.0, 40.0, 0.1), (150, 150, 150))]


def _floor_frame(pose):
    return render_boxes(FLOOR, K, pose, H, W)


def _uniform_features(vec, valid_hw=None):
    """PixelFeatures giving every pixel the same vector."""
    idx = np.zeros((H, W), np.int32)
    return PixelFeatures(np.asarray(vec, np.float32)[None], idx)


def test_plane_recovered_within_millimetres_from_noisy_views():
    rng = np.random.default_rng(0)
    fmap = PointFusionMap(4, max_depth=4.0)
    poses = orbit_poses((0.0, 0.0, 0.0), 1.0, 1.2, 8, sweep_deg=60.0)
    for pose in poses:
        f = _floor_frame(pose)
        noisy = f.depth + rng.normal(0.0, 0.001, f.depth.shape).astype(np.float32)
        fmap.integrate(f.rgb, noisy, K, pose)
    z = fmap.points[:, 2]
    assert np.sqrt(np.mean(z**2)) < 0.002  # single-frame noise is 1 mm in depth
    assert np.abs(z).max() < 0.01
    merged = fmap.confidence > 1.5  # seen in at least two frames
    assert merged.mean() > 0.5
    # normals point up within a few degrees
    cos = fmap.normals @ np.array([0.0, 0.0, 1.0])
    assert np.median(cos) > np.cos(np.radians(3.0))


def test_identical_frames_merge_instead_of_duplicating():
    pose = look_at((0.3, -0.4, 1.0), (0.0, 0.0, 0.0))
    f = _floor_frame(pose)
    fmap = PointFusionMap(3)
    s1 = fmap.integrate(f.rgb, f.depth, K, pose, _uniform_features([1, 0, 0]))
    conf1 = fmap.confidence
    s2 = fmap.integrate(f.rgb, f.depth, K, pose, _uniform_features([1, 0, 0]))
    assert s1.added == len(fmap) and s2.added == 0 and s2.merged == s1.added
    assert np.allclose(fmap.confidence, 2 * conf1)
    # the border has no normal: (H-2)(W-2) pixels are fused
    assert len(fmap) == (H - 2) * (W - 2)


def test_positions_and_features_are_confidence_weighted_means():
    pose = look_at((0.0, 0.0, 1.0), (0.0, 0.001, 0.0))
    f = _floor_frame(pose)
    fmap = PointFusionMap(3, slots=4)
    fmap.integrate(f.rgb, f.depth, K, pose, _uniform_features([1, 0, 0]))
    fmap.integrate(f.rgb, f.depth + 0.01, K, pose, _uniform_features([0, 1, 0]))
    fmap.integrate(f.rgb, f.depth + 0.02, K, pose, _uniform_features([0, 0, 2]))
    # Equal alpha per pixel across frames: position = mean of the three depths' vertices,
    # about 1 cm below the first frame's plane; feature = normalise(e1 + e2 + 2 e3) (eq. 1).
    centre = fmap.points[np.argmin(np.linalg.norm(fmap.points[:, :2], axis=1))]
    assert centre[2] == pytest.approx(-0.01, abs=1e-4)
    expect = np.array([1.0, 1.0, 2.0]) / np.sqrt(6.0)
    assert np.allclose(fmap.features(), expect, atol=1e-5)
    assert np.allclose(fmap.scores(np.array([0.0, 0.0, 1.0])), 2 / np.sqrt(6.0), atol=1e-5)


def test_feature_beyond_slots_credits_the_most_similar_entry():
    pose = look_at((0.0, 0.0, 1.0), (0.0, 0.001, 0.0))
    f = _floor_frame(pose)
    fmap = PointFusionMap(3, slots=2)
    for v in ([1, 0, 0], [0, 1, 0], [0.9, 0.1, 0.0]):  # the third is closest to e1
        fmap.integrate(f.rgb, f.depth, K, pose, _uniform_features(v))
    # the third observation is credited to e1: S = 2a e1 + a e2
    assert np.allclose(fmap.features(), np.array([2.0, 1.0, 0.0]) / np.sqrt(5.0), atol=1e-5)


def test_zero_features_never_dilute():
    pose = look_at((0.2, 0.0, 1.0), (0.0, 0.0, 0.0))
    f = _floor_frame(pose)
    fmap = PointFusionMap(3)
    fmap.integrate(f.rgb, f.depth, K, pose, _uniform_features([0, 1, 0]))
    fc = fmap.feature_confidence
    fmap.integrate(f.rgb, f.depth, K, pose, None)
    fmap.integrate(f.rgb, f.depth, K, pose, np.zeros((H, W, 3), np.float32))
    assert np.allclose(fmap.feature_confidence, fc)
    assert np.allclose(fmap.confidence, 3 * fc)
    assert np.allclose(fmap.features(), [0, 1, 0], atol=1e-6)


def test_points_beyond_distance_threshold_do_not_merge():
    pose = look_at((0.0, 0.0, 1.0), (0.0, 0.001, 0.0))
    f = _floor_frame(pose)
    fmap = PointFusionMap(3, dist_th=0.05)
    fmap.integrate(f.rgb, f.depth, K, pose)
    n = len(fmap)
    stats = fmap.integrate(f.rgb, f.depth - 0.1, K, pose)  # 10 cm closer
    assert stats.merged == 0 and len(fmap) == 2 * n


def test_radial_confidence_prefers_the_image_centre():
    pose = look_at((0.0, 0.0, 1.0), (0.0, 0.001, 0.0))
    f = _floor_frame(pose)
    fmap = PointFusionMap(3)
    fmap.integrate(f.rgb, f.depth, K, pose)
    xy = np.linalg.norm(fmap.points[:, :2], axis=1)
    conf = fmap.confidence
    assert conf[np.argmin(xy)] == pytest.approx(1.0, abs=1e-3)
    # the outermost fused pixel is (1, 1) (the border has no normal): offset (-30.5, -22.5)
    # from the principal point, half-diagonal^2 = 32^2 + 24^2 = 1600, gamma^2 = 0.89781,
    # alpha = exp(-0.89781 / (2 * 0.6^2)) = 0.28738
    assert conf[np.argmax(xy)] == pytest.approx(0.28738, abs=1e-4)


def test_invalid_depth_is_skipped():
    pose = look_at((0.0, 0.0, 1.0), (0.0, 0.001, 0.0))
    f = _floor_frame(pose)
    depth = f.depth.copy()
    depth[10, 10] = np.nan
    depth[20, 20] = -1.0
    depth[30, 30] = np.inf
    depth[5, 40] = 0.0
    fmap = PointFusionMap(3)
    stats = fmap.integrate(f.rgb, depth, K, pose)
    assert np.all(np.isfinite(fmap.points))
    # each bad pixel removes itself and (through the normal stencil) up to 4 neighbours
    assert (H - 2) * (W - 2) - 20 <= len(fmap) < (H - 2) * (W - 2) - 4
    assert stats.skipped == H * W - len(fmap)


def test_bad_inputs_get_clear_errors():
    pose = look_at((0.0, 0.0, 1.0), (0.0, 0.001, 0.0))
    f = _floor_frame(pose)
    fmap = PointFusionMap(3)
    with pytest.raises(ShapeError, match=r"rgb_hw3: expected shape \(48, 64, 3\)"):
        fmap.integrate(f.rgb[:10], f.depth, K, pose)
    with pytest.raises(DtypeError, match="millimetres"):
        fmap.integrate(f.rgb, (f.depth * 1000).astype(np.uint16), K, pose)
    scaled = pose.copy()
    scaled[:3, :3] *= 1.1
    with pytest.raises(PoseError, match="rigid"):
        fmap.integrate(f.rgb, f.depth, K, scaled)
    with pytest.raises(PoseError, match="bottom row"):
        bad = pose.copy()
        bad[3, 0] = 1.0
        fmap.integrate(f.rgb, f.depth, K, bad)
    with pytest.raises(ShapeError, match="feats_hwd"):
        fmap.integrate(f.rgb, f.depth, K, pose, np.ones((H, W, 5), np.float32))
    with pytest.raises(ValueError, match="finite features"):
        fmap.integrate(f.rgb, f.depth, K, pose, np.full((H, W, 3), np.nan, np.float32))
    with pytest.raises(ValueError, match="K_33"):
        fmap.integrate(f.rgb, f.depth, np.zeros((3, 3)), pose)
    with pytest.raises(ValueError, match="dist_th"):
        PointFusionMap(3, dist_th=-1.0)
    with pytest.raises(ValueError, match="non-zero"):
        fmap.scores(np.zeros(3))
    assert len(fmap) == 0  # nothing was fused by the failed calls


def test_compiled_frame_points_match_the_numpy_reference():
    from conceptfusion.map import _kernels
    from conceptfusion.cameras import backproject, normal_map, radial_confidence, transform_directions, transform_points

    pose = look_at((0.4, -0.3, 0.9), (0.0, 0.1, 0.0))
    f = render_boxes(FLOOR + [Box("cube", (0.0, 0.0, 0.1), (0.2, 0.2, 0.2), (200, 0, 0))], K, pose, H, W)
    depth = f.depth.copy()
    depth[3, 7] = np.nan
    conf = radial_confidence(H, W, K)
    pix, obs, alpha = _kernels.frame_points(depth, f.rgb.astype(np.float32), K, pose, np.float32(10.0), conf)
    v = backproject(depth, K, max_depth=10.0)
    n = normal_map(v)
    valid = np.flatnonzero(np.isfinite(n[..., 0]).ravel())
    assert np.array_equal(pix, valid)
    assert np.allclose(obs[:, :3], transform_points(pose, v.reshape(-1, 3)[valid]), atol=1e-5)
    assert np.allclose(obs[:, 3:6], transform_directions(pose, n.reshape(-1, 3)[valid]), atol=1e-5)
    assert np.array_equal(obs[:, 6:], f.rgb.reshape(-1, 3)[valid].astype(np.float32))
    assert np.array_equal(alpha, conf.ravel()[valid])


def test_compact_features_equal_exact_running_means_within_slots():
    # Fuse frames whose per-pixel features differ, then compare with a brute-force
    # dense running mean (eq. 1) tracked for the points that exist from frame one.
    rng = np.random.default_rng(3)
    pose = look_at((0.0, 0.0, 1.0), (0.0, 0.001, 0.0))
    f = _floor_frame(pose)
    fmap = PointFusionMap(6, slots=4)
    dense_sum = None
    for t in range(4):
        pal = rng.normal(size=(5, 6)).astype(np.float32)
        idx = rng.integers(-1, 5, size=(H, W)).astype(np.int32)
        fmap.integrate(f.rgb, f.depth, K, pose, PixelFeatures(pal, idx))
        alpha = fmap.confidence / (t + 1)  # the same alpha every frame at a fixed pose
        feat = np.concatenate([pal, np.zeros((1, 6), np.float32)])[idx[1:-1, 1:-1].ravel()]
        contrib = alpha[:, None] * feat
        dense_sum = contrib if dense_sum is None else dense_sum + contrib
    expect = dense_sum / np.maximum(np.linalg.norm(dense_sum, axis=1, keepdims=True), 1e-12)
    assert np.allclose(fmap.features(), expect, atol=1e-5)
    q = rng.normal(size=6)
    cos = expect @ q / np.linalg.norm(q)
    has = np.linalg.norm(dense_sum, axis=1) > 0
    assert np.allclose(fmap.scores(q)[has], cos[has], atol=1e-5)
    assert np.isnan(fmap.scores(q)[~has]).all()
