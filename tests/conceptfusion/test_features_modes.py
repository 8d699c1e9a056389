"""Ablation variants of the pixel-aligned features: full, global only, local only."""

import numpy as np
import pytest

from conceptfusion.perception.features import pixel_aligned_palette, region_features
from conceptfusion.perception.pipeline import frame_features


def _unit(x):
    return x / np.linalg.norm(x, axis=-1, keepdims=True)


def test_global_and_local_modes_pick_one_side_of_eq6():
    g = np.array([1.0, 0.0, 0.0])
    local = np.array([[0.0, 2.0, 0.0], [0.0, 0.0, 3.0]])
    np.testing.assert_allclose(region_features(g, local, mode="global"), [[1, 0, 0], [1, 0, 0]], atol=1e-6)
    np.testing.assert_allclose(region_features(g, local, mode="local"), [[0, 1, 0], [0, 0, 1]], atol=1e-6)
    full = region_features(g, local, mode="full")
    assert np.all(full[:, 0] > 0) and np.all(full[:, 0] < 1)  # a mix of both
    np.testing.assert_allclose(full, region_features(g, local), atol=0)  # the default is unchanged


def test_palette_in_global_mode_gives_every_masked_pixel_the_global_feature():
    masks = np.zeros((2, 4, 5), bool)
    masks[0, :2] = True
    masks[1, 1:3, :3] = True
    g = np.array([0.0, 0.0, 2.0])
    pf = pixel_aligned_palette(g, np.eye(3)[:2], masks, mode="global")
    dense = pf.dense()
    covered = masks.any(axis=0)
    np.testing.assert_allclose(dense[covered], np.tile([0, 0, 1], (covered.sum(), 1)), atol=1e-6)
    assert not dense[~covered].any()


class _CountingEncoder:
    dim = 3

    def __init__(self):
        self.images = 0

    def encode_image(self, images):
        self.images += len(images)
        return _unit(np.array([[float(im.mean()) + 1.0, 1.0, 0.5] for im in images]))


def test_frame_features_global_mode_encodes_only_the_frame():
    rgb = np.random.default_rng(0).integers(0, 255, (6, 8, 3), dtype=np.uint8)
    masks = np.zeros((3, 6, 8), bool)
    masks[0, :3], masks[1, 3:], masks[2, :, :2] = True, True, True
    enc = _CountingEncoder()
    frame_features(rgb, masks, enc, mode="global")
    assert enc.images == 1
    frame_features(rgb, masks, enc, mode="local")
    assert enc.images == 1 + 4


def test_unknown_mode_is_rejected():
    with pytest.raises(ValueError, match=r"mode: expected one of \('full', 'global', 'local'\), got 'both'"):
        region_features(np.ones(3), np.ones((1, 3)), mode="both")
