"""The perceived featurizer: what a robot can perceive (mask proposals and an encoder, eqs. 3-6)."""

from __future__ import annotations

from typing import Iterable, Mapping

from conceptfusion.frames import RGBDFrame
from conceptfusion.perception.featurizer_base import EncoderBacked
from conceptfusion.perception.features import PixelFeatures, check_mode
from conceptfusion.perception.pipeline import frame_features
from conceptfusion.perception.score_floor import FLOOR_SETTINGS, encoder_score_floor

__all__ = ["PerceivedFeaturizer", "encoder_vocabulary"]


def encoder_vocabulary(encoder) -> tuple[str, ...]:
    """The names an encoder's image side was trained to tell apart, sorted: the train categories
    its metadata records (``info["splits"]["categories"]["train"]``, written by
    :mod:`tower_training.train_v2`); empty when it records none (the v1 tower, CLIP and other
    open encoders, text-only encoders).

    Raises:
        ValueError: the metadata holds a train list that is not a list of non-empty names.
    """
    info = getattr(encoder, "info", None)
    names = (((info or {}).get("splits") or {}).get("categories") or {}).get("train") if isinstance(info, dict) else None
    if names is None:
        return ()
    if not isinstance(names, (list, tuple)) or not all(isinstance(n, str) and n.strip() for n in names):
        raise ValueError(f"encoder metadata: splits.categories.train: expected a list of non-empty names, got {names!r:.200}")
    return tuple(sorted(set(names)))


class PerceivedFeaturizer(EncoderBacked):
    """Mask proposals + encoder embeddings mixed by eqs. 3-6 (what a robot can perceive).

    Args:
        encoder: image + text encoder (``encode_image``, ``encode_text``, ``dim``).
        proposer: mask proposer (``propose(rgb, depth, K)``; a privileged one also gets
            ``segmentation_hw``).
        mode: pixel-feature variant (``"full"``, ``"global"``, ``"local"``).
        uniqueness: use eq. 5's uniqueness term.
        score_floor: the text-query floor in every setting; default: the encoder's calibrated
            ones per setting (``score_floors``, see :func:`~conceptfusion.perception.score_floor.score_floor_for`; ``score_floor`` is
            the tabletop one), else None.
    """

    def __init__(self, encoder, proposer, *, mode: str = "full", uniqueness: bool = True,
                 score_floor: float | None = ...) -> None:  # type: ignore[assignment]
        if proposer is None:
            raise ValueError("PerceivedFeaturizer: expected a mask proposer (make_proposer('rgbd'); "
                             "or make_featurizer('oracle') for ground-truth features)")
        self._encoder, self.proposer = encoder, proposer
        self.mode, self.uniqueness = check_mode(mode), bool(uniqueness)
        self.score_floors = {k: encoder_score_floor(encoder, k) if score_floor is ... else score_floor for k in FLOOR_SETTINGS}
        self.score_floor = self.score_floors["tabletop"]
        self.privileged = bool(getattr(proposer, "privileged", False))
        self.vocabulary = encoder_vocabulary(encoder)
        """Names the encoder's image side was trained on (:func:`encoder_vocabulary`)."""

    def reset(self, label_names: Mapping[int, str] | None = None,
              label_phrases: Mapping[int, Iterable[str]] | None = None) -> None:
        """Nothing to forget (the names and phrases are for the oracles only)."""

    def features(self, frame: RGBDFrame) -> PixelFeatures:
        """Masks from the proposer, then :func:`~conceptfusion.perception.pipeline.frame_features`.

        Shape:
            frame (H, W) -> PixelFeatures (H, W).
        """
        if self.privileged:
            if frame.segmentation is None:
                raise ValueError("PerceivedFeaturizer: the ground-truth proposer needs the frame's segmentation")
            masks = self.proposer.propose(frame.rgb, frame.depth, frame.K, segmentation_hw=frame.segmentation)
        else:
            masks = self.proposer.propose(frame.rgb, frame.depth, frame.K)
        return frame_features(frame.rgb, masks, self._encoder, uniqueness=self.uniqueness, mode=self.mode)
