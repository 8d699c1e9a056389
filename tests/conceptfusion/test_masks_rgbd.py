"""The default RGB-D mask proposer on exact synthetic box scenes."""

from __future__ import annotations

import numpy as np
import pytest

from conceptfusion.cameras import backproject, intrinsics_from_fovy, transform_points
from conceptfusion.perception.encoders import ColorNameEncoder
from conceptfusion.errors import DtypeError, ShapeError
from conceptfusion.perception.masks.base import MaskProposer
from conceptfusion.perception.masks.rgbd import RGBDProposer, frame_config
from conceptfusion.perception.masks.rgbd_config import RGBDProposerConfig
from conceptfusion.perception.pipeline import frame_features
from conceptfusion.synthetic import Box, look_at, orbit_poses, render_boxes, tabletop_boxes

H, W = 240, 320
K = intrinsics_from_fovy(60.0, W, H)
BOXES = tabletop_boxes()
FLOOR, TABLE = 0, 1
OBJECTS = range(2, len(BOXES))
TABLE_TOP_Z = BOXES[TABLE].hi[2]
POSES = orbit_poses((0.0, 0.0, 0.45), 1.3, 0.8, 3, start_deg=10.0) + orbit_poses(
    (0.0, 0.0, 0.45), 0.9, 0.5, 2, start_deg=40.0, sweep_deg=180.0
)


@pytest.fixture(scope="module")
def frames():
    return [render_boxes(BOXES, K, pose, H, W) for pose in POSES]


@pytest.fixture(scope="module")
def proposer():
    return RGBDProposer()


@pytest.fixture(scope="module")
def proposals(frames, proposer):
    return [proposer.segment(f.rgb, f.depth, f.K) for f in frames]


def _iou(masks_rhw, truth_hw):
    inter = (masks_rhw & truth_hw).sum(axis=(1, 2))
    union = (masks_rhw | truth_hw).sum(axis=(1, 2))
    return inter / np.maximum(union, 1)


def _table_top_and_floor(frame):
    """Ground-truth pixels of the floor and of the table's top face."""
    pts = transform_points(frame.cam_to_world, backproject(frame.depth, frame.K).astype(np.float64))
    top = (frame.segmentation == TABLE) & (np.abs(pts[..., 2] - TABLE_TOP_Z) < 1e-3)
    return frame.segmentation == FLOOR, top


def test_is_a_mask_proposer(proposer):
    assert isinstance(proposer, MaskProposer)
    assert proposer.privileged is False


def test_every_object_gets_a_proposal_with_iou_at_least_half(frames, proposals):
    best = []
    for f, (masks, _) in zip(frames, proposals):
        assert masks.dtype == bool and masks.shape[1:] == (H, W)
        for obj in OBJECTS:
            truth = f.segmentation == obj
            if truth.sum() >= 50:
                best.append(_iou(masks, truth).max() if len(masks) else 0.0)
    best = np.array(best)
    assert len(best) >= 25
    assert best.min() >= 0.5, f"worst best-IoU {best.min():.3f}, mean best-IoU {best.mean():.3f} over {len(best)} objects"
    assert best.mean() >= 0.85, f"mean best-IoU {best.mean():.3f} over {len(best)} objects"


def test_proposals_overlap_across_levels(frames, proposals):
    """Some object has a part proposal (a face) inside a whole-object proposal."""
    nested = 0
    for f, (masks, level) in zip(frames, proposals):
        assert len(set(level.tolist())) >= 2
        assert (masks.sum(axis=0) >= 2).any()
        for obj in OBJECTS:
            truth = f.segmentation == obj
            if not truth.any():
                continue
            iou = _iou(masks, truth)
            inside = (masks & truth).sum(axis=(1, 2)) / np.maximum(masks.sum(axis=(1, 2)), 1)
            whole = np.flatnonzero(iou >= 0.8)
            parts = np.flatnonzero((inside >= 0.9) & (iou < 0.8))
            if any((masks[p] & ~masks[o]).sum() <= 0.05 * masks[p].sum() for o in whole for p in parts):
                nested += 1
    assert nested >= 5, f"only {nested} objects have a part proposal nested in a whole-object proposal"


def test_floor_and_table_top_are_filtered_by_default(frames, proposals):
    for f, (masks, _) in zip(frames, proposals):
        floor, top = _table_top_and_floor(f)
        background = floor | top
        share = (masks & background).sum(axis=(1, 2)) / masks.sum(axis=(1, 2))
        assert share.max() < 0.5, f"a proposal lies {share.max():.2f} on the floor or the table top"


def test_background_planes_kept_as_one_mask_each_when_asked(frames):
    proposer = RGBDProposer(keep_background_planes=True)
    f = frames[0]
    masks = proposer.propose(f.rgb, f.depth, f.K)
    floor, top = _table_top_and_floor(f)
    assert (_iou(masks, floor) >= 0.95).sum() == 1
    assert (_iou(masks, top) >= 0.95).sum() == 1
    # fragments of either plane are still dropped
    share = (masks & (floor | top)).sum(axis=(1, 2)) / masks.sum(axis=(1, 2))
    assert ((share >= 0.5) & (_iou(masks, floor) < 0.95) & (_iou(masks, top) < 0.95)).sum() == 0


def test_plane_alone_gives_no_mask_and_box_on_plane_gives_the_box():
    floor = Box("floor", (0.0, 0.0, -0.05), (6.0, 6.0, 0.1), (150, 150, 150))
    cube = Box("cube", (0.0, 0.0, 0.1), (0.2, 0.2, 0.2), (200, 30, 30))
    pose = look_at((0.9, -0.6, 0.8), (0.0, 0.0, 0.1))
    proposer = RGBDProposer()
    empty = render_boxes([floor], K, pose, H, W)
    assert proposer.propose(empty.rgb, empty.depth, K).shape == (0, H, W)
    assert RGBDProposer(keep_background_planes=True).propose(empty.rgb, empty.depth, K).shape == (1, H, W)
    scene = render_boxes([floor, cube], K, pose, H, W)
    masks = proposer.propose(scene.rgb, scene.depth, K)
    assert _iou(masks, scene.segmentation == 1).max() >= 0.9


def test_fixed_size_pixels_resolves_smaller_things_in_larger_frames():
    """A 6 cm cube 2.9 m away covers 4 pixels of a 160x120 frame and 29 of a 320x240 one: the
    default proposer (regions scale with the frame: 77 pixels at least at 320x240) misses it at
    both sizes; with region sizes held at a 160x120 frame's, the larger frame segments it."""
    floor = Box("floor", (0.0, 0.0, -0.05), (8.0, 8.0, 0.1), (150, 150, 150))
    cube = Box("cube", (0.0, 0.0, 0.03), (0.06, 0.06, 0.06), (200, 30, 30))
    pose = look_at((2.4, -1.6, 1.2), (0.0, 0.0, 0.0))
    fixed = RGBDProposer(fixed_size_pixels=160 * 120)
    for w, h in ((160, 120), (320, 240)):
        k = intrinsics_from_fovy(60.0, w, h)
        f = render_boxes([floor, cube], k, pose, h, w)
        default, small = RGBDProposer().propose(f.rgb, f.depth, k), fixed.propose(f.rgb, f.depth, k)
        assert len(default) == 0 or _iou(default, f.segmentation == 1).max() < 0.5
        if w == 160:  # a frame of the fixed size is segmented exactly as by default
            assert np.array_equal(small, default)
        else:
            assert _iou(small, f.segmentation == 1).max() >= 0.9
    cfg = fixed.config
    assert frame_config(cfg, 160 * 120) is cfg and frame_config(RGBDProposerConfig(), 320 * 240) == RGBDProposerConfig()
    big = frame_config(cfg, 320 * 240)
    assert (big.fine_scale, big.min_area_fraction) == (cfg.fine_scale / 4, cfg.min_area_fraction / 4)
    assert frame_config(RGBDProposerConfig(fixed_size_pixels=10**6), 100).min_area_fraction == cfg.max_area_fraction  # capped


def test_nan_depth_is_invalid_and_handled(frames, proposer):
    f = frames[0]
    depth = f.depth.copy()
    depth[:, : W // 3] = np.nan
    depth[0, -1] = -1.0
    masks = proposer.propose(f.rgb, depth, f.K)
    valid = np.isfinite(depth) & (depth > 0)
    share_valid = (masks & valid).sum(axis=(1, 2)) / masks.sum(axis=(1, 2))
    assert share_valid.min() >= proposer.config.min_valid_fraction
    seen = [obj for obj in OBJECTS if (f.segmentation[:, W // 3 + 5:] == obj).sum() >= 100
            and not (f.segmentation[:, : W // 3 + 5] == obj).any()]
    assert seen
    for obj in seen:
        assert _iou(masks, f.segmentation == obj).max() >= 0.5
    nothing = np.full((H, W), np.nan, np.float32)
    assert proposer.propose(f.rgb, nothing, f.K).shape == (0, H, W)


def test_noisy_sensor_depth_with_median_filter(frames):
    """0.5% multiplicative depth noise and RGB noise, as a depth camera gives; median on."""
    rng = np.random.default_rng(0)
    proposer = RGBDProposer(depth_median_px=5)
    best = []
    for f in frames[:3]:
        depth = (f.depth * (1.0 + 0.005 * rng.standard_normal(f.depth.shape))).astype(np.float32)
        rgb = np.clip(f.rgb + rng.normal(0.0, 3.0, f.rgb.shape), 0, 255).astype(np.uint8)
        masks = proposer.propose(rgb, depth, f.K)
        best += [_iou(masks, f.segmentation == obj).max() for obj in OBJECTS if (f.segmentation == obj).sum() >= 100]
    assert np.mean(best) >= 0.75, f"mean best-IoU {np.mean(best):.3f} on noisy depth"


def test_deterministic(frames, proposer, proposals):
    f = frames[1]
    again, level = RGBDProposer().segment(f.rgb, f.depth.astype(np.float64), f.K)
    np.testing.assert_array_equal(again, proposals[1][0])
    np.testing.assert_array_equal(level, proposals[1][1])


def test_output_sorted_by_area_and_capped(frames):
    f = frames[0]
    masks = RGBDProposer(max_masks=3).propose(f.rgb, f.depth, f.K)
    assert len(masks) == 3
    areas = masks.sum(axis=(1, 2))
    assert np.all(np.diff(areas) <= 0)


def test_masks_feed_the_feature_pipeline(frames, proposals):
    f = frames[0]
    enc = ColorNameEncoder()
    feats = frame_features(f.rgb, proposals[0][0], enc)
    dense = feats.dense()
    red = dense[f.segmentation == 2].mean(axis=0)
    names = ["red", "green", "blue", "yellow", "purple", "orange", "brown", "gray"]
    sims = enc.encode_text(names) @ red
    assert names[int(np.argmax(sims))] == "red"


@pytest.mark.parametrize(
    "rgb, depth, k, err, match",
    [
        (np.zeros((H, W, 3), np.float32), np.ones((H, W), np.float32), K, DtypeError, "uint8"),
        (np.zeros((H, W), np.uint8), np.ones((H, W), np.float32), K, ShapeError, r"rgb_hw3: expected shape \(\*, \*, 3\)"),
        (np.zeros((H, W, 3), np.uint8), np.ones((H, W), np.uint16), K, DtypeError, "millimetres"),
        (np.zeros((H, W, 3), np.uint8), np.ones((H, W + 1), np.float32), K, ShapeError, "image's size"),
        (np.zeros((H, W, 3), np.uint8), np.ones((H, W), np.float32), np.eye(2), ShapeError, "K_33"),
        (np.zeros((H, W, 3), np.uint8), np.ones((H, W), np.float32), -K, ValueError, "fx, fy > 0"),
        (np.zeros((2, 2, 3), np.uint8), np.ones((2, 2), np.float32), K, ShapeError, "at least 3x3"),
        ("image", np.ones((H, W), np.float32), K, DtypeError, "numpy array"),
    ],
)
def test_bad_inputs(proposer, rgb, depth, k, err, match):
    with pytest.raises(err, match=match):
        proposer.propose(rgb, depth, k)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"merge_thresholds": (4.0, 2.0)}, "ascending"),
        ({"merge_thresholds": (0.0,)}, "positive"),
        ({"fine_scale": 0.0}, "fine_scale"),
        ({"min_area_fraction": 0.7, "max_area_fraction": 0.6}, "min <= max"),
        ({"dedupe_iou": 1.5}, "dedupe_iou: expected a fraction"),
        ({"normal_tol_deg": 200.0}, "normal_tol_deg"),
        ({"max_masks": 0}, "max_masks"),
        ({"depth_median_px": 7}, "depth_median_px"),
        ({"fixed_size_pixels": -1}, r"fixed_size_pixels: expected an integer pixel count >= 0 \(0: off\), got -1"),
        ({"fixed_size_pixels": True}, "fixed_size_pixels"),
    ],
)
def test_bad_config(kwargs, match):
    with pytest.raises(ValueError, match=match):
        RGBDProposerConfig(**kwargs)


def test_config_overrides_and_type_checks():
    p = RGBDProposer(RGBDProposerConfig(max_masks=5), dedupe_iou=0.8)
    assert (p.config.max_masks, p.config.dedupe_iou) == (5, 0.8)
    with pytest.raises(TypeError, match="RGBDProposerConfig"):
        RGBDProposer({"max_masks": 5})
    with pytest.raises(TypeError):
        RGBDProposer(no_such_setting=1)
