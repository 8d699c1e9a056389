"""Privileged oracle features: ground-truth segmentation mapped to text embeddings.

**Privileged.** The oracle reads the simulator's instance segmentation, which a robot does
not have. It gives each pixel the text embedding of its object's name, so a map fused from
oracle features is what perfect perception would produce. Use it for upper bounds and for
agent regression tests that must not depend on perception quality; every result built on it
must say so (:attr:`OracleFeatures.privileged` is ``True``).
"""

from __future__ import annotations

from typing import Mapping, Protocol, Sequence

import numpy as np

from conceptfusion._checks import as_array
from conceptfusion.perception.features import PixelFeatures

__all__ = ["OracleFeatures", "TextEmbedder"]


class TextEmbedder(Protocol):
    """Anything with ``encode_text(texts) -> (n, d)`` unit rows and ``dim``."""

    @property
    def dim(self) -> int: ...

    def encode_text(self, texts: Sequence[str]) -> np.ndarray: ...


class OracleFeatures:
    """Pixel features from instance segmentation and object names (privileged).

    Args:
        text_encoder: embeds object names; queries must use the same encoder.
        names: object name (or description) per segmentation id. Ids missing from the
            mapping (background, walls you chose to leave out) get no feature.
    """

    privileged = True

    def __init__(self, text_encoder: TextEmbedder, names: Mapping[int, str]) -> None:
        if not names:
            raise ValueError("names: expected at least one segmentation id -> name entry")
        ids = np.array(sorted(int(k) for k in names), dtype=np.int64)
        if ids.min() < 0:
            raise ValueError(f"names: expected segmentation ids >= 0, got {int(ids.min())}")
        self.dim = int(text_encoder.dim)
        self._ids = ids
        self._palette = np.asarray(text_encoder.encode_text([names[int(i)] for i in ids]), np.float32)
        self._lut = np.full(int(ids.max()) + 2, -1, np.int32)  # last slot: ids out of range
        self._lut[ids] = np.arange(len(ids), dtype=np.int32)

    def __call__(self, segmentation_hw: np.ndarray) -> PixelFeatures:
        """Features of one frame from its instance segmentation (-1 or unknown ids: none).

        Shape:
            ``segmentation_hw`` (H, W) int -> PixelFeatures of (H, W).
        """
        seg = as_array("segmentation_hw", segmentation_hw, shape=(None, None), kinds="iu").astype(np.int64)
        idx = np.where((seg >= 0) & (seg < len(self._lut) - 1), seg, len(self._lut) - 1)
        return PixelFeatures(self._palette, self._lut[idx])
