"""The frame featurizer protocol (:class:`FrameFeaturizer`) and what the perceived and oracle
featurizers share (:class:`EncoderBacked`)."""

from __future__ import annotations

from typing import Iterable, Mapping, Protocol, Sequence, runtime_checkable

import numpy as np

from conceptfusion.frames import RGBDFrame
from conceptfusion.perception.features import PixelFeatures

__all__ = ["FrameFeaturizer", "EncoderBacked"]


@runtime_checkable
class FrameFeaturizer(Protocol):
    """One posed RGB-D frame to pixel-aligned features, and texts to the same space."""

    privileged: bool
    """True when the features read ground truth (the oracle, ground-truth masks); results
    built on them must say so."""
    score_floor: float | None
    """The smallest median cosine score of a region that counts as found for a text query
    (calibrated per encoder; None: no floor).

    A featurizer may also say which names its image side was trained to tell apart
    (``vocabulary``, a tuple of str; see :func:`~conceptfusion.perception.perceived.encoder_vocabulary`); callers read it with
    ``getattr(featurizer, "vocabulary", ())``."""

    @property
    def dim(self) -> int:
        """Feature dimension ``d``."""
        ...

    @property
    def encoder(self):
        """The underlying encoder (``encode_text``; ``encode_image`` too unless text-only),
        for image and click queries against the map."""
        ...

    def encode_text(self, texts: Sequence[str]) -> np.ndarray:
        """Unit embeddings of ``texts`` in the features' space. Shape: (n,) -> (n, d) float32."""
        ...

    def reset(self, label_names: Mapping[int, str] | None = None,
              label_phrases: Mapping[int, Iterable[str]] | None = None) -> None:
        """Start a new scene; ``label_names`` (segmentation id -> name) is what the oracle
        needs, ``label_phrases`` (segmentation id -> every phrase its object answers to) what
        the ``oracle-open`` needs; the others ignore both."""
        ...

    def features(self, frame: RGBDFrame) -> PixelFeatures:
        """Features of one frame. Shape: frame of (H, W) -> PixelFeatures of (H, W)."""
        ...


class EncoderBacked:
    """What the perceived and the oracle featurizer share: the feature space is their encoder's (``dim``,
    ``encode_text``), and the encoder answers image and click queries."""

    _encoder = None

    @property
    def dim(self) -> int:
        return int(self._encoder.dim)

    @property
    def encoder(self):
        return self._encoder

    def encode_text(self, texts: Sequence[str]) -> np.ndarray:
        return self._encoder.encode_text(texts)
