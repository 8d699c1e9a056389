"""Faster perception paths give exactly what the plain formulation gives: the palette of mask
sets, the tower's preprocessing, and the embedded encoder's cache (batches, threads, repeats)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from conceptfusion.perception.encoders import ColorNameEncoder
from conceptfusion.perception.features import _unique_rows, pixel_aligned_palette, region_features
from conceptfusion.perception.image_tower import SHIPPED_TOWER_DIR, EmbeddedEncoder, preprocess

pytest.importorskip("onnxruntime")


def _ref_palette(glob, local, masks):
    """Mask sets packed into bytes (mask 0 the most significant bit), distinct rows by bytes."""
    r, h, w = masks.shape
    f_p = region_features(glob, local).astype(np.float64)
    codes = np.ascontiguousarray(np.packbits(masks.reshape(r, h * w), axis=0).T)
    _, first, inverse = _unique_rows(codes)
    members = np.unpackbits(codes[first], axis=1, count=r).astype(np.float64)
    covered = members.any(axis=1)
    palette = members[covered] @ f_p
    palette = (palette / (np.linalg.norm(palette, axis=-1, keepdims=True) + 1e-8)).astype(np.float32)
    remap = np.full(len(first), -1, dtype=np.int32)
    remap[covered] = np.arange(int(covered.sum()), dtype=np.int32)
    return palette, remap[inverse.ravel()].reshape(h, w)


@pytest.mark.parametrize("num_masks", [1, 7, 8, 9, 19, 64, 70])
def test_palette_of_mask_sets_equals_the_byte_formulation(num_masks):
    rng = np.random.default_rng(num_masks)
    h, w = 30, 40
    masks = np.zeros((num_masks, h, w), bool)
    for m in masks:  # overlapping boxes
        r0, c0 = rng.integers(0, h - 5), rng.integers(0, w - 5)
        m[r0 : r0 + rng.integers(3, 20), c0 : c0 + rng.integers(3, 25)] = True
    glob, local = rng.normal(size=16), rng.normal(size=(num_masks, 16))
    want_palette, want_index = _ref_palette(glob, local, masks)
    got = pixel_aligned_palette(glob, local, masks)
    assert len(want_palette) >= min(num_masks, 2) and (want_index == -1).any()
    assert np.array_equal(got.palette_pd, want_palette) and np.array_equal(got.index_hw, want_index)


def _ref_preprocess(images, size):
    out = np.empty((len(images), 3, size, size), np.float32)
    for i, img in enumerate(images):
        h, w = img.shape[:2]
        side = max(h, w)
        fill = img.reshape(-1, 3).mean(axis=0)
        square = np.empty((side, side, 3), np.uint8)
        square[:] = fill.astype(np.uint8)
        top, left = (side - h) // 2, (side - w) // 2
        square[top : top + h, left : left + w] = img
        interp = cv2.INTER_AREA if side > size else cv2.INTER_LINEAR
        small = cv2.resize(square, (size, size), interpolation=interp)
        mean, std = np.array([0.485, 0.456, 0.406], np.float32), np.array([0.229, 0.224, 0.225], np.float32)
        out[i] = ((small.astype(np.float32) / 255.0 - mean) / std).transpose(2, 0, 1)
    return out


def _crops(n, seed):
    rng = np.random.default_rng(seed)
    frame = rng.integers(0, 256, (120, 160, 3), dtype=np.uint8)
    out = []
    for _ in range(n):
        r0, c0 = rng.integers(0, 100), rng.integers(0, 140)
        out.append(frame[r0 : r0 + rng.integers(1, 21), c0 : c0 + rng.integers(1, 21)])  # views, as crops are
    return [frame] + out


def test_preprocess_equals_the_per_crop_formula():
    images = _crops(40, 0) + [np.full((64, 64, 3), 7, np.uint8), np.zeros((5, 5, 3), np.uint8)]
    for size in (16, 64):
        assert np.array_equal(preprocess(images, size), _ref_preprocess(images, size))


class _Text:
    """A text tower stand-in of the shipped tower's size (the image side is what is tested)."""

    dim = 384

    def encode_text(self, texts):
        return ColorNameEncoder(dim=384).encode_text(texts)


def test_cache_batches_threads_and_repeats_change_no_embedding():
    crops = _crops(30, 1)
    plain = EmbeddedEncoder(SHIPPED_TOWER_DIR, _Text(), cache_size=0, threads=1)
    want = plain.encode_image(crops)
    assert want.shape == (31, 384) and np.allclose(np.linalg.norm(want, axis=1), 1.0, atol=1e-5)
    one_by_one = np.concatenate([plain.encode_image([c]) for c in crops])
    assert np.array_equal(one_by_one, want)
    cached = EmbeddedEncoder(SHIPPED_TOWER_DIR, _Text(), cache_size=16, batch_size=7)
    assert np.array_equal(cached.encode_image(crops[:12]), want[:12])
    mixed = [crops[5], crops[20], crops[5].copy(), crops[0], crops[29]]  # cached, new, repeated
    assert np.array_equal(cached.encode_image(mixed), want[[5, 20, 5, 0, 29]])
    assert np.array_equal(cached.encode_image(crops), want)
    assert len(cached._cache) == 16  # bounded: least recently used dropped


@pytest.mark.parametrize("kwargs, match", [({"cache_size": -1}, "cache_size"), ({"threads": 0}, "threads"),
                                           ({"batch_size": 2.5}, "batch_size")])
def test_bad_encoder_settings(kwargs, match):
    with pytest.raises(ValueError, match=match):
        EmbeddedEncoder(SHIPPED_TOWER_DIR, _Text(), **kwargs)


def test_thread_count_comes_from_cf_threads(monkeypatch):
    from conceptfusion.perception.encoders import THREADS_ENV, default_threads, onnx_session_options

    monkeypatch.delenv(THREADS_ENV, raising=False)
    assert default_threads() == 2 and onnx_session_options(None).intra_op_num_threads == 2
    monkeypatch.setenv(THREADS_ENV, "1")
    assert onnx_session_options(None).intra_op_num_threads == 1
    assert onnx_session_options(3).intra_op_num_threads == 3  # an explicit count wins
    assert EmbeddedEncoder(SHIPPED_TOWER_DIR, _Text()).encode_image(_crops(2, 0)).shape == (3, 384)
    for bad in ("0", "two", "-1"):
        monkeypatch.setenv(THREADS_ENV, bad)
        with pytest.raises(ValueError, match=f"CF_THREADS.*{bad}"):
            EmbeddedEncoder(SHIPPED_TOWER_DIR, _Text())
