"""Privileged oracle features: ground-truth segmentation mapped to concept vectors.

**Privileged.** Both oracles read the simulator's instance segmentation, which a robot does
not have. Use them for upper bounds and for agent regression tests that must not depend on
perception quality; every result built on them must say so (``privileged`` is ``True``).

* :class:`OracleFeatures` gives each pixel the text embedding of its object's name, so a map
  fused from it is what perfect perception *of names* would produce: a closed vocabulary, a
  query is found when its embedding is close to a name's (a synonym, a function or a parent
  group of the name is not).
* :class:`GroundedOracleFeatures` is ground-truth segmentation **and** ground-truth grounding
  of descriptions: label ``k`` gets the basis vector ``e_k`` of :data:`GROUNDED_ORACLE_DIM`
  dimensions, and a description is embedded as the normalised sum of the basis vectors of the
  labels that answer to it (each label comes with its phrase set: name, synonyms,
  colour/material + name, functions, parent groups). Referent points score ``1/sqrt(m)`` (``m``
  labels answer), every other point exactly 0; a description nothing answers to gets the
  reserved last basis vector, which no pixel carries, so every point scores 0 and the query is
  not found. It answers every description the phrase sets cover, and only those.
"""

from __future__ import annotations

import math
import re
from typing import Iterable, Mapping, Protocol, Sequence

import numpy as np

from conceptfusion._checks import as_array
from conceptfusion.perception.features import PixelFeatures

__all__ = [
    "OracleFeatures", "TextEmbedder", "GroundedOracleFeatures", "GROUNDED_ORACLE_DIM", "GROUNDED_ORACLE_MIN_SCORE",
    "normalize_phrase", "drop_small_segments", "check_min_pixels",
]

GROUNDED_ORACLE_DIM = 256
"""Feature dimension of :class:`GroundedOracleFeatures`: label ids ``0..D-2`` get basis
vectors, the last one is reserved for "nothing answers"."""

GROUNDED_ORACLE_MIN_SCORE = 0.5 / math.sqrt(GROUNDED_ORACLE_DIM - 1)
"""Score floor with grounded oracle features (about 0.031), derived, not tuned: a referent's
points score ``1/sqrt(m)`` with ``m <= D - 1`` labels answering, at least ``1/sqrt(D - 1)``
(0.063), and every other point exactly 0 (points fused from several labels score in
between). Half the smallest referent score keeps every referent region and rejects a region
whose median point is not a referent."""

_ARTICLE = re.compile(r"^(?:the|a|an)\s+")


class TextEmbedder(Protocol):
    """Anything with ``encode_text(texts) -> (n, d)`` unit rows and ``dim``."""

    @property
    def dim(self) -> int: ...

    def encode_text(self, texts: Sequence[str]) -> np.ndarray: ...


def check_min_pixels(min_pixels) -> int:
    """``min_pixels`` when it is an integer >= 0 (a bool is not); ValueError naming it otherwise."""
    if isinstance(min_pixels, bool) or not isinstance(min_pixels, int) or min_pixels < 0:
        raise ValueError(f"min_pixels: expected an integer >= 0, got {min_pixels!r}")
    return min_pixels


def drop_small_segments(segmentation_hw, min_pixels: int) -> np.ndarray:
    """The segmentation with every segment of fewer than ``min_pixels`` pixels set to -1 (no
    object), so an oracle labels only what the frame shows at least that large.

    Shape:
        (H, W) int -> (H, W) int64 (a copy; ``min_pixels`` 0 or 1 keeps every segment).

    Raises:
        ValueError: ``min_pixels`` is not an integer >= 0.
    """
    check_min_pixels(min_pixels)
    seg = as_array("segmentation_hw", segmentation_hw, shape=(None, None), kinds="iu").astype(np.int64)
    if min_pixels <= 1:
        return seg
    valid = seg >= 0
    counts = np.bincount(seg[valid], minlength=1)
    small = np.zeros(seg.shape, bool)
    small[valid] = counts[seg[valid]] < min_pixels
    seg[small] = -1
    return seg


def _segment_features(segmentation_hw, palette_kd: np.ndarray, lut: np.ndarray) -> PixelFeatures:
    """Each pixel's palette row through ``lut`` (segmentation id -> row; its last entry, -1,
    stands for -1 and ids past the table), as PixelFeatures.

    Shape:
        (H, W) int, (k, D), (max_id + 2,) int32 -> PixelFeatures of (H, W).
    """
    seg = as_array("segmentation_hw", segmentation_hw, shape=(None, None), kinds="iu").astype(np.int64)
    idx = np.where((seg >= 0) & (seg < len(lut) - 1), seg, len(lut) - 1)
    return PixelFeatures(palette_kd, lut[idx])


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
        return _segment_features(segmentation_hw, self._palette, self._lut)


def normalize_phrase(text: str) -> str:
    """The form descriptions are compared in: lower case, stripped, single spaces, without a
    leading article (``"the "``, ``"a "``, ``"an "``). ``"  The  Red Mug"`` -> ``"red mug"``."""
    if not isinstance(text, str):
        raise TypeError(f"phrase: expected a string, got {type(text).__name__}")
    return _ARTICLE.sub("", " ".join(text.lower().split()))


class GroundedOracleFeatures:
    """Orthogonal codes per segmentation id, and descriptions grounded in them (privileged).

    Args:
        phrases: per segmentation id, every phrase its object answers to (``"the mug"``,
            ``"the coffee mug"``, ``"something to drink from"``, ...). Ids missing from the
            mapping (background, walls you chose to leave out) get no feature; an id with no
            phrase gets its code but no description reaches it.
        dim: feature dimension ``D`` (default :data:`GROUNDED_ORACLE_DIM`); ids must be below
            ``D - 1`` (the last basis vector means "nothing answers").

    Raises:
        ValueError: no entry, a negative id or an id >= ``D - 1``.
        TypeError: a phrase set that is a bare string or holds a non-string.
    """

    privileged = True

    def __init__(self, phrases: Mapping[int, Iterable[str]], *, dim: int = GROUNDED_ORACLE_DIM) -> None:
        if not phrases:
            raise ValueError("phrases: expected at least one segmentation id -> phrases entry")
        if not isinstance(dim, int) or dim < 2:
            raise ValueError(f"dim: expected an int >= 2, got {dim!r}")
        ids = np.array(sorted(int(k) for k in phrases), dtype=np.int64)
        if ids.min() < 0:
            raise ValueError(f"phrases: expected segmentation ids >= 0, got {int(ids.min())}")
        if ids.max() >= dim - 1:
            raise ValueError(f"phrases: expected segmentation ids below {dim - 1} (dim {dim}, the last basis vector is "
                             f"reserved for 'nothing answers'), got id {int(ids.max())}; build it with a larger dim")
        self.dim = int(dim)
        self._index: dict[str, list[int]] = {}
        for k in ids.tolist():
            group = phrases[k]
            if isinstance(group, str):
                raise TypeError(f"phrases[{k}]: expected a collection of phrases, got the string {group!r}")
            for text in sorted({normalize_phrase(t) for t in group}):
                self._index.setdefault(text, []).append(k)
        self._ids = ids
        self._palette = np.zeros((len(ids), self.dim), np.float32)
        self._palette[np.arange(len(ids)), ids] = 1.0
        self._lut = np.full(int(ids.max()) + 2, -1, np.int32)  # last slot: ids out of range
        self._lut[ids] = np.arange(len(ids), dtype=np.int32)

    def referents(self, text: str) -> list[int]:
        """The segmentation ids that answer to ``text`` (compared by :func:`normalize_phrase`), sorted."""
        return list(self._index.get(normalize_phrase(text), ()))

    def encode_text(self, texts: Sequence[str]) -> np.ndarray:
        """Each text grounded: the normalised sum of its referents' basis vectors, or the
        reserved last basis vector when no label answers.

        Shape:
            (n,) -> (n, D) float32 unit rows.
        """
        if isinstance(texts, str):
            raise TypeError("texts: expected a sequence of strings, got one string (wrap it in a list)")
        out = np.zeros((len(texts), self.dim), np.float32)
        for row, text in enumerate(texts):
            ks = self.referents(text)
            if ks:
                out[row, ks] = 1.0 / math.sqrt(len(ks))
            else:
                out[row, self.dim - 1] = 1.0
        return out

    def __call__(self, segmentation_hw: np.ndarray) -> PixelFeatures:
        """Features of one frame from its instance segmentation (-1 or unknown ids: none).

        Shape:
            ``segmentation_hw`` (H, W) int -> PixelFeatures of (H, W) over a (k, D) palette.
        """
        return _segment_features(segmentation_hw, self._palette, self._lut)
