"""Pixel-aligned features: paper eqs. 3-6 against values worked out by hand."""

import numpy as np
import pytest

from conceptfusion.errors import ShapeError
from conceptfusion.perception.features import (
    PixelFeatures,
    crop_masks,
    mask_bboxes,
    mixing_weights,
    pixel_aligned_features,
    pixel_aligned_palette,
    region_features,
)

E1, E2, E3 = np.eye(3)
DIAG = (E1 + E2) / np.sqrt(2.0)


def test_one_region_takes_the_global_feature():
    # R = 1: softmax over one region gives w = 1, so f_P = f_G.
    w = mixing_weights(E1, E2[None])
    assert w == pytest.approx([1.0])
    masks = np.ones((1, 2, 2), bool)
    feats = pixel_aligned_features(E1, E2[None], masks)
    assert np.allclose(feats, E1)


def test_two_regions_golden_values():
    # phi = (0, 1/sqrt2); phibar = (1/2)(1/sqrt2) for both, so w = softmax(0, 0.70711)
    # = (1 / (1 + e^0.70711), ...) = (0.33024, 0.66976).
    w = mixing_weights(E1, np.stack([E2, DIAG]))
    assert w == pytest.approx([0.33024, 0.66976], abs=1e-4)
    # f_P1 = 0.33024 e1 + 0.66976 e2 -> /0.74676 = (0.44222, 0.89690, 0)
    # f_P2 = 0.66976 e1 + 0.33024 (e1 + e2)/sqrt2 = (0.90328, 0.23351, 0) -> (0.96817, 0.25029, 0)
    fp = region_features(E1, np.stack([E2, DIAG]))
    assert fp[0] == pytest.approx([0.44222, 0.89690, 0.0], abs=1e-4)
    assert fp[1] == pytest.approx([0.96817, 0.25029, 0.0], abs=1e-4)


def test_uniqueness_term_on_and_off():
    # L = (e2, e2, e3), G = e1: phi = 0 for all; cos(L1, L2) = 1, the rest 0.
    # phibar = (1/3, 1/3, 0): w = (e^(1/3), e^(1/3), 1) / 3.79122 = (0.36812, 0.36812, 0.26377).
    local = np.stack([E2, E2, E3])
    assert mixing_weights(E1, local) == pytest.approx([0.36812, 0.36812, 0.26377], abs=1e-4)
    assert mixing_weights(E1, local, uniqueness=False) == pytest.approx([1 / 3] * 3, abs=1e-9)
    fp = region_features(E1, local)
    # f_P3 = 0.26377 e1 + 0.73623 e3 -> /0.78206 = (0.33727, 0, 0.94141)
    assert fp[2] == pytest.approx([0.33727, 0.0, 0.94141], abs=1e-4)


def test_temperature_flattens_weights():
    local = np.stack([E2, DIAG])
    sharp = mixing_weights(E1, local, tau=0.1)
    flat = mixing_weights(E1, local, tau=100.0)
    assert sharp[1] > 0.99
    assert flat == pytest.approx([0.5, 0.5], abs=0.01)


def _two_overlapping_masks():
    m = np.zeros((2, 1, 4), bool)
    m[0, 0, :2] = True  # pixels 0, 1
    m[1, 0, 1:3] = True  # pixels 1, 2; pixel 3 has no mask
    return m


def test_overlapping_masks_in_both_orders():
    masks = _two_overlapping_masks()
    local = np.stack([E2, DIAG])
    f = pixel_aligned_features(E1, local, masks)
    # overlap: normalise(f_P1 + f_P2) = (1.41039, 1.14719, 0) / 1.81804 = (0.77578, 0.63100, 0)
    assert f[0, 1] == pytest.approx([0.77578, 0.63100, 0.0], abs=1e-4)
    assert f[0, 0] == pytest.approx([0.44222, 0.89690, 0.0], abs=1e-4)
    assert f[0, 2] == pytest.approx([0.96817, 0.25029, 0.0], abs=1e-4)
    assert np.all(f[0, 3] == 0.0)  # no mask -> zero vector
    g = pixel_aligned_features(E1, local[::-1], masks[::-1])
    assert np.allclose(f, g, atol=1e-6)


def test_palette_is_compact_and_matches_dense():
    masks = _two_overlapping_masks()
    pf = pixel_aligned_palette(E1, np.stack([E2, DIAG]), masks)
    assert pf.palette_pd.shape == (3, 3)  # {1}, {1, 2}, {2}; the empty set has no entry
    assert pf.index_hw[0, 3] == -1
    assert np.allclose(np.linalg.norm(pf.palette_pd, axis=1), 1.0)
    back = PixelFeatures.from_dense(pf.dense())
    assert np.array_equal(back.dense(), pf.dense())
    assert len(back.palette_pd) == 3


def test_many_masks_more_than_one_byte_of_membership():
    rng = np.random.default_rng(0)
    masks = rng.random((19, 6, 7)) > 0.5
    local = rng.normal(size=(19, 8))
    glob = rng.normal(size=8)
    f = pixel_aligned_features(glob, local, masks)
    fp = region_features(glob, local)
    for r, c in [(0, 0), (3, 4), (5, 6)]:
        s = fp[masks[:, r, c]].sum(axis=0)
        expect = s / np.linalg.norm(s) if np.any(masks[:, r, c]) else np.zeros(8)
        assert np.allclose(f[r, c], expect, atol=1e-5)


def test_bboxes_and_crops():
    m = np.zeros((2, 5, 6), bool)
    m[0, 1:3, 2:5] = True
    m[1, 4, 0] = True
    assert mask_bboxes(m).tolist() == [[1, 2, 3, 5], [4, 0, 5, 1]]
    img = np.arange(5 * 6 * 3, dtype=np.uint8).reshape(5, 6, 3)
    crops = crop_masks(img, m)
    assert crops[0].shape == (2, 3, 3) and np.array_equal(crops[0], img[1:3, 2:5])
    with pytest.raises(ValueError, match="empty"):
        mask_bboxes(np.zeros((1, 3, 3), bool))


def test_bad_inputs():
    with pytest.raises(ShapeError, match=r"local_feats_rd: expected shape \(\*, 3\)"):
        mixing_weights(E1, np.ones((2, 4)))
    with pytest.raises(ShapeError, match="masks_rhw"):
        pixel_aligned_features(E1, np.stack([E2, E3]), np.ones((3, 2, 2), bool))
    with pytest.raises(ShapeError, match="image's size"):
        pixel_aligned_palette(E1, E2[None], np.ones((1, 2, 2), bool), image_hw=(3, 3))
    with pytest.raises(ValueError, match="finite"):
        mixing_weights(np.array([np.nan, 0, 0]), E2[None])
    with pytest.raises(ValueError, match="boolean masks"):
        pixel_aligned_features(E1, E2[None], np.full((1, 2, 2), 3))
    with pytest.raises(ValueError, match="tau"):
        mixing_weights(E1, E2[None], tau=0.0)
    with pytest.raises(ShapeError, match="index_hw"):
        PixelFeatures(np.eye(2, dtype=np.float32), np.full((2, 2), 5, np.int32))
