"""The privileged oracle featurizers: ground-truth segmentation labelled with name embeddings
(:class:`OracleFeaturizer`, ``"oracle"``) or with ground-truth grounding of descriptions
(:class:`GroundedOracleFeaturizer`, ``"oracle-open"``). Results built on them must say so."""

from __future__ import annotations

from typing import Iterable, Mapping, Sequence

import numpy as np

from conceptfusion.frames import RGBDFrame
from conceptfusion.perception.featurizer_base import EncoderBacked
from conceptfusion.perception.features import PixelFeatures
from conceptfusion.perception.oracle import (GROUNDED_ORACLE_DIM, GroundedOracleFeatures, OracleFeatures, check_min_pixels,
                                             drop_small_segments)
from conceptfusion.perception.score_floor import ORACLE_MIN_SCORE, ORACLE_OPEN_MIN_SCORE

__all__ = ["OracleFeaturizer", "GroundedOracleFeaturizer"]


class OracleFeaturizer(EncoderBacked):
    """Privileged features: each segment labelled with its name's text embedding.

    Args:
        text_encoder: embeds the names and the queries (``encode_text``, ``dim``).
        score_floor: the text-query floor (default :data:`~conceptfusion.perception.score_floor.ORACLE_MIN_SCORE`).
        min_pixels: segments smaller than this many pixels of a frame get no feature
            (:func:`~conceptfusion.perception.oracle.drop_small_segments`; 0: every segment).
    """

    privileged = True
    vocabulary: tuple[str, ...] = ()
    """No learned image side: nothing to contrast a name with."""

    def __init__(self, text_encoder, *, score_floor: float | None = ORACLE_MIN_SCORE, min_pixels: int = 0) -> None:
        self._encoder = text_encoder
        self.score_floor = score_floor
        self.min_pixels = check_min_pixels(min_pixels)
        self._features: OracleFeatures | None = None

    def reset(self, label_names: Mapping[int, str] | None = None,
              label_phrases: Mapping[int, Iterable[str]] | None = None) -> None:
        """Embed the names of the segmentation ids of the new scene (required; ``label_phrases``
        is ignored)."""
        if not label_names:
            raise ValueError("OracleFeaturizer.reset: expected object names by segmentation id (privileged oracle features)")
        self._features = OracleFeatures(self._encoder, dict(label_names))

    def features(self, frame: RGBDFrame) -> PixelFeatures:
        """Features from ``frame.segmentation`` (required).

        Shape:
            frame (H, W) with segmentation (H, W) int -> PixelFeatures (H, W).
        """
        if self._features is None:
            raise RuntimeError("OracleFeaturizer: call reset(label_names) before features()")
        if frame.segmentation is None:
            raise ValueError("OracleFeaturizer.features: expected the frame's segmentation (privileged)")
        return self._features(drop_small_segments(frame.segmentation, self.min_pixels))


class _GroundingEncoder:
    """The text side of a :class:`GroundedOracleFeaturizer` (``encode_text``, ``dim``), for
    code that asks the featurizer's ``encoder``; text only (no ``encode_image``: image
    queries are not supported)."""

    def __init__(self, featurizer: "GroundedOracleFeaturizer") -> None:
        self._featurizer = featurizer

    @property
    def dim(self) -> int:
        return self._featurizer.dim

    def encode_text(self, texts: Sequence[str]) -> np.ndarray:
        return self._featurizer.encode_text(texts)


class GroundedOracleFeaturizer:
    """Privileged features with ground-truth grounding of descriptions (encoder ``"oracle-open"``).

    Each segment gets an orthogonal code; a text is embedded as the codes of the segments of the
    current scene whose phrase sets contain it (:class:`~conceptfusion.perception.oracle.GroundedOracleFeatures`),
    so text embeddings depend on the scene (:attr:`scene_dependent_text`): a mapper must not
    keep them across :meth:`reset`. Image queries are not supported (the encoder is text only).

    Args:
        dim: feature dimension (segmentation ids must be below ``dim - 1``).
        score_floor: the text-query floor (default :data:`~conceptfusion.perception.score_floor.ORACLE_OPEN_MIN_SCORE`, derived from
            the construction).
        min_pixels: segments smaller than this many pixels of a frame get no feature, an oracle
            that recognises perfectly only what a frame shows at least that large
            (``"oracle-open:min_pixels=N"``; 0: every segment, however small).
    """

    privileged = True
    vocabulary: tuple[str, ...] = ()
    """No learned image side: nothing to contrast a name with."""
    scene_dependent_text = True
    """Text embeddings are the current scene's (a mapper clears its text cache on reset)."""

    def __init__(self, *, dim: int = GROUNDED_ORACLE_DIM, score_floor: float | None = ORACLE_OPEN_MIN_SCORE,
                 min_pixels: int = 0) -> None:
        if not isinstance(dim, int) or dim < 2:
            raise ValueError(f"GroundedOracleFeaturizer: dim: expected an int >= 2, got {dim!r}")
        self._dim = dim
        self.score_floor = score_floor
        self.min_pixels = check_min_pixels(min_pixels)
        self._features: GroundedOracleFeatures | None = None
        self._encoder = _GroundingEncoder(self)

    @property
    def dim(self) -> int:
        return self._dim

    @property
    def encoder(self):
        """A text-only encoder (``encode_text``, ``dim``) grounding texts in the current scene."""
        return self._encoder

    def reset(self, label_names: Mapping[int, str] | None = None,
              label_phrases: Mapping[int, Iterable[str]] | None = None) -> None:
        """Ground the new scene: ``label_phrases`` (segmentation id -> every phrase its object
        answers to) is required; ``label_names`` is not used (a name counts only as one of the
        phrases).

        Raises:
            ValueError: no phrases, or a segmentation id >= ``dim - 1``.
        """
        if not label_phrases:
            raise ValueError("GroundedOracleFeaturizer.reset: expected the phrases each object answers to by segmentation id "
                             "(label_phrases; the environment's privileged info['object_phrases']), got none")
        self._features = GroundedOracleFeatures(dict(label_phrases), dim=self._dim)

    def _grounding(self, what: str) -> GroundedOracleFeatures:
        if self._features is None:
            raise RuntimeError(f"GroundedOracleFeaturizer: call reset(label_phrases=...) before {what}")
        return self._features

    def encode_text(self, texts: Sequence[str]) -> np.ndarray:
        """Texts grounded in the current scene. Shape: (n,) -> (n, dim) float32 unit rows."""
        return self._grounding("encode_text()").encode_text(texts)

    def features(self, frame: RGBDFrame) -> PixelFeatures:
        """Features from ``frame.segmentation`` (required).

        Shape:
            frame (H, W) with segmentation (H, W) int -> PixelFeatures (H, W).
        """
        grounding = self._grounding("features()")
        if frame.segmentation is None:
            raise ValueError("GroundedOracleFeaturizer.features: expected the frame's segmentation (privileged)")
        return grounding(drop_small_segments(frame.segmentation, self.min_pixels))
