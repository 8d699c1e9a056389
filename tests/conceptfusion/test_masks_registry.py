"""Proposer registry, the ground-truth proposer and the optional SAM backend's error paths."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest

from conceptfusion.cameras import intrinsics_from_fovy
from conceptfusion.errors import CheckpointError, MissingDependencyError, ShapeError
from conceptfusion.perception.masks.base import GroundTruthProposer, MaskProposer
from conceptfusion.perception.masks.registry import PROPOSERS, make_proposer
from conceptfusion.perception.masks.rgbd import RGBDProposer
from conceptfusion.perception.masks.sam import SamConfig, SamProposer, infer_model_type

H, W = 6, 8
K = intrinsics_from_fovy(60.0, W, H)
RGB = np.zeros((H, W, 3), np.uint8)
DEPTH = np.ones((H, W), np.float32)
_HAS_SAM = any(importlib.util.find_spec(m) is not None for m in ("segment_anything", "mobile_sam"))


def test_registry_is_a_plain_dict_with_the_three_proposers():
    assert type(PROPOSERS) is dict
    assert set(PROPOSERS) == {"rgbd", "sam", "gt"}


def test_make_proposer_by_name():
    assert isinstance(make_proposer(), RGBDProposer)
    assert isinstance(make_proposer(" RGBD "), RGBDProposer)
    gt = make_proposer("gt")
    assert isinstance(gt, GroundTruthProposer) and gt.privileged is True
    assert isinstance(gt, MaskProposer)


@pytest.mark.parametrize(
    "spec, match",
    [
        ("rbgd", r"unknown mask proposer 'rbgd'; did you mean 'rgbd'"),
        ("sma:/x.pth", r"did you mean 'sam'"),
        ("mask2former", r"registered: gt, rgbd, sam"),
        ("sam", r"expected a checkpoint path"),
        ("rgbd:fast", r"expected KEY=VALUE settings separated by commas, got 'fast'"),
        ("rgbd:fine_scel=3", r"'fine_scel' is not a setting; expected one of .*fine_scale"),
        ("rgbd:max_masks=1.5", r"max_masks expects an int, got '1.5'"),
        ("rgbd:keep_background_planes=yes", r"keep_background_planes expects true or false"),
        ("rgbd:merge_thresholds=2/x", r"merge_thresholds expects numbers separated by /"),
        ("rgbd:fine_scale=1,fine_scale=2", r"'fine_scale' given twice"),
        ("rgbd:min_area_fraction=2", r"min_area_fraction: expected a fraction in \[0, 1\], got 2.0"),
        ("gt:1", r"takes no argument"),
    ],
)
def test_make_proposer_bad_specs(spec, match):
    with pytest.raises(ValueError, match=match):
        make_proposer(spec)


def test_rgbd_spec_overrides_settings():
    p = make_proposer("rgbd: min_area_fraction=0.00025, fine_scale=15,max_masks=128,merge_thresholds=2/5,keep_background_planes=TRUE")
    assert isinstance(p, RGBDProposer)
    assert (p.config.min_area_fraction, p.config.fine_scale, p.config.max_masks) == (0.00025, 15.0, 128)
    assert p.config.merge_thresholds == (2.0, 5.0) and p.config.keep_background_planes is True
    assert p.config.dedupe_iou == RGBDProposer().config.dedupe_iou  # the rest keep their defaults
    assert make_proposer("rgbd").config == RGBDProposer().config


def test_make_proposer_needs_a_string():
    with pytest.raises(TypeError, match="proposer name"):
        make_proposer(3)


def test_sam_spec_with_missing_checkpoint(tmp_path):
    with pytest.raises(CheckpointError, match="does not exist"):
        make_proposer(f"sam:{tmp_path / 'sam_vit_h_missing.pth'}")


def test_ground_truth_masks_in_id_order_with_ignored_ids():
    seg = np.full((H, W), -1, np.int32)
    seg[:2, :3] = 4
    seg[3:, :] = 0
    seg[0, 7] = 2
    masks = GroundTruthProposer(ignore_ids=(0,)).propose(RGB, DEPTH, K, segmentation_hw=seg)
    assert masks.shape == (2, H, W) and masks.dtype == bool
    np.testing.assert_array_equal(masks[0], seg == 2)
    np.testing.assert_array_equal(masks[1], seg == 4)
    assert GroundTruthProposer(min_area_px=2).from_segmentation(seg).shape == (2, H, W)  # ids 0 and 4
    assert GroundTruthProposer().from_segmentation(np.full((H, W), -1)).shape == (0, H, W)


def test_ground_truth_needs_its_segmentation():
    gt = GroundTruthProposer()
    with pytest.raises(ValueError, match="privileged"):
        gt.propose(RGB, DEPTH, K)
    with pytest.raises(ShapeError, match="segmentation_hw: expected the image's size"):
        gt.propose(RGB, DEPTH, K, segmentation_hw=np.zeros((H + 1, W), np.int32))
    with pytest.raises(TypeError, match="segmentation_hw"):
        gt.from_segmentation(np.zeros((H, W), np.float32))
    with pytest.raises(ValueError, match="min_area_px"):
        GroundTruthProposer(min_area_px=0)


def test_sam_defaults_are_the_official_settings():
    cfg = SamConfig()
    assert (cfg.points_per_side, cfg.pred_iou_thresh, cfg.crop_n_layers, cfg.crop_n_points_downscale_factor) == (
        8, 0.92, 1, 2,
    )
    with pytest.raises(ValueError, match="pred_iou_thresh"):
        SamConfig(pred_iou_thresh=1.5)
    with pytest.raises(ValueError, match="points_per_side"):
        SamConfig(points_per_side=0)


def _fake_checkpoint(path):
    torch = pytest.importorskip("torch")
    torch.save({"not": torch.zeros(1)}, path)
    return path


@pytest.mark.skipif(_HAS_SAM, reason="a SAM package is installed: the missing-package path cannot be reached")
def test_sam_without_the_package_names_the_extra(tmp_path):
    ckpt = _fake_checkpoint(tmp_path / "sam_vit_b_01ec64.pth")
    with pytest.raises(MissingDependencyError, match=r'pip install "conceptfusion-harness\[sam\]"') as info:
        SamProposer(ckpt)
    assert "segment_anything" in str(info.value)
    assert isinstance(info.value, ImportError)
    with pytest.raises(MissingDependencyError, match="mobile_sam"):
        SamProposer(_fake_checkpoint(tmp_path / "mobile_sam.pt"))


@pytest.mark.parametrize(
    "content, match",
    [(b"", "is empty"), (b"not a checkpoint at all", "not a PyTorch checkpoint")],
)
def test_sam_rejects_corrupt_checkpoints_before_importing(tmp_path, content, match):
    path = tmp_path / "sam_vit_h_4b8939.pth"
    path.write_bytes(content)
    with pytest.raises(CheckpointError, match=match):
        SamProposer(path)


def test_sam_rejects_directories_and_non_paths(tmp_path):
    with pytest.raises(CheckpointError, match="not a file"):
        SamProposer(tmp_path)
    with pytest.raises(TypeError, match="expected a path"):
        SamProposer(42)


def test_sam_model_type_from_file_name(tmp_path):
    from pathlib import Path

    assert infer_model_type(Path("sam_vit_h_4b8939.pth")) == "vit_h"
    assert infer_model_type(Path("SAM_VIT_B_01ec64.pth")) == "vit_b"
    assert infer_model_type(Path("mobile_sam.pt")) == "vit_t"
    with pytest.raises(ValueError, match="pass model_type="):
        infer_model_type(Path("weights.pth"))
    ckpt = _fake_checkpoint(tmp_path / "weights.pth")
    with pytest.raises(ValueError, match="model_type: expected one of"):
        SamProposer(ckpt, model_type="vit_x")


def test_sam_with_the_package_rejects_weights_of_another_model(tmp_path):
    pytest.importorskip("segment_anything")
    ckpt = _fake_checkpoint(tmp_path / "sam_vit_b_01ec64.pth")
    with pytest.raises(CheckpointError, match="could not be loaded as a vit_b SAM model"):
        SamProposer(ckpt)
