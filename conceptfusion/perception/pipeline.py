"""From one RGB frame, its masks and an encoder to pixel-aligned features."""

from __future__ import annotations

import numpy as np

from conceptfusion.perception.encoders import Encoder
from conceptfusion.perception.features import PixelFeatures, check_mode, crop_masks, pixel_aligned_palette

__all__ = ["frame_features"]


def frame_features(
    rgb_hw3: np.ndarray,
    masks_rhw: np.ndarray,
    encoder: Encoder,
    *,
    tau: float = 1.0,
    uniqueness: bool = True,
    mode: str = "full",
) -> PixelFeatures:
    """Pixel-aligned features of a frame: global embedding, one batched call for all mask
    crops (tight boxes), then the paper's mixing (eqs. 3-6).

    ``mode`` picks the ablation variant (:func:`~conceptfusion.perception.features.region_features`):
    ``"full"`` (default), ``"global"`` (masked pixels get the frame's embedding; no crop is
    encoded) or ``"local"`` (each mask's crop embedding only).

    Shape:
        ``rgb_hw3`` (H, W, 3) uint8, ``masks_rhw`` (R, H, W) bool -> PixelFeatures (H, W).
    """
    check_mode(mode)
    masks = np.asarray(masks_rhw, bool)
    if mode == "global":
        g = encoder.encode_image([rgb_hw3])[0]
        local = np.repeat(np.asarray(g)[None], len(masks), axis=0)
        return pixel_aligned_palette(g, local, masks, tau=tau, uniqueness=uniqueness, image_hw=rgb_hw3.shape[:2], mode=mode)
    images = [rgb_hw3] + (crop_masks(rgb_hw3, masks) if len(masks) else [])
    emb = encoder.encode_image(images)
    return pixel_aligned_palette(
        emb[0], emb[1:], masks, tau=tau, uniqueness=uniqueness, image_hw=rgb_hw3.shape[:2], mode=mode
    )
