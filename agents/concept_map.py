"""Online ConceptFusion mapping for agents: frames in, 3D answers to text queries out.

A :class:`ConceptMapper` owns a :class:`~conceptfusion.map.fusion.PointFusionMap`, an encoder and a
mask proposer, and turns each posed RGB-D observation into pixel-aligned features (paper
eqs. 3-6) fused into the map (eqs. 1-2). Agents ask it where a described object is
(:meth:`ConceptMapper.locate`) and get a 3D region or an explicit "not found".

Two perception modes:

* **perceived** (default): mask proposals from the RGB-D frame and crop/frame embeddings from
  an encoder (the embedded tower, or any registry encoder such as real CLIP);
* **oracle** (privileged): each pixel gets the text embedding of its ground-truth object's
  name (:class:`~conceptfusion.perception.oracle.OracleFeatures`); it needs the simulator's segmentation,
  which the caller passes explicitly. Results built on it must say they are privileged.

A single-frame (2.5D) agent uses the same mapper with ``persistent=False``: every frame
replaces the map, so answers come from the current view only.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from conceptfusion.map.fusion import PointFusionMap
from conceptfusion.perception.oracle import OracleFeatures
from conceptfusion.perception.pipeline import frame_features
from conceptfusion.map.query import NEGATIVE_PHRASES, QueryResult, locate

__all__ = ["ConceptMapper", "MapperConfig", "frame_from_observation"]


@dataclass(frozen=True)
class MapperConfig:
    """How observations become a map."""

    persistent: bool = True
    """Keep fusing into one map (False: each frame replaces the map, the 2.5D baseline)."""
    max_depth: float = 6.0
    """Depth beyond this (m) is ignored (far walls add points, not answers)."""
    voxel_size: float = 0.03
    """Voxel size (m) of the connectivity that groups selected points into regions."""
    min_points: int = 20
    """Smallest region (points) that counts as a found object."""
    relevancy_threshold: float = 0.6
    """Calibrated decision against generic phrases (see :func:`conceptfusion.map.query.locate`)."""
    min_score: float | None = None
    """Also require the best region's median cosine score to reach this (None: no such test).
    Generic negatives do not reject a near-miss ("brown bottle" for "the black bottle" scores
    0.70 with MiniLM text features, "object" 0.35), so an encoder-specific floor does: exact
    names score >= 0.9 with oracle features."""


def frame_from_observation(observation: Mapping) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The posed RGB-D frame in an observation: ``rgb``, ``depth``, ``K``, ``cam_to_world``.

    Shape:
        returns rgb (H, W, 3) uint8, depth (H, W) float32, K (3, 3), cam_to_world (4, 4).
    """
    missing = [k for k in ("rgb", "depth", "K", "cam_to_world") if k not in observation]
    if missing:
        raise KeyError(f"observation: expected a posed RGB-D frame with keys rgb, depth, K, cam_to_world; missing {missing}")
    return (
        np.asarray(observation["rgb"]),
        np.asarray(observation["depth"], np.float32),
        np.asarray(observation["K"], np.float64),
        np.asarray(observation["cam_to_world"], np.float64),
    )


class ConceptMapper:
    """Fuse observations into a concept map and answer text queries.

    Args:
        encoder: image + text encoder (``encode_image``, ``encode_text``, ``dim``). In oracle
            mode only ``encode_text`` is used.
        proposer: mask proposer (``propose(rgb, depth, K)``); ignored in oracle mode.
        config: see :class:`MapperConfig`.
        oracle: privileged perception from ground-truth segmentation.
    """

    def __init__(self, encoder, proposer=None, config: MapperConfig = MapperConfig(), *, oracle: bool = False) -> None:
        if not oracle and proposer is None:
            raise ValueError("ConceptMapper: expected a mask proposer (or oracle=True for ground-truth features)")
        self.encoder, self.proposer, self.config, self.oracle = encoder, proposer, config, bool(oracle)
        self._text_cache: dict[str, np.ndarray] = {}
        self._negatives = None
        self._oracle_features: OracleFeatures | None = None
        self.map = PointFusionMap(encoder.dim, max_depth=config.max_depth)
        self.frames = 0

    @property
    def privileged(self) -> bool:
        """True when the map is built from ground truth (oracle features or a ground-truth proposer)."""
        return self.oracle or bool(getattr(self.proposer, "privileged", False))

    def reset(self, object_names: Mapping[int, str] | None = None) -> None:
        """Start an empty map. Oracle mode needs the names of the segmentation ids."""
        self.map = PointFusionMap(self.encoder.dim, max_depth=self.config.max_depth)
        self.frames = 0
        if self.oracle:
            if not object_names:
                raise ValueError("ConceptMapper(oracle=True).reset: expected object names by segmentation id")
            self._oracle_features = OracleFeatures(self.encoder, dict(object_names))

    def text_vector(self, text: str) -> np.ndarray:
        """The encoder's unit embedding of ``text`` (cached)."""
        if not isinstance(text, str) or not text.strip():
            raise ValueError(f"query: expected a non-empty description, got {text!r}")
        if text not in self._text_cache:
            self._text_cache[text] = np.asarray(self.encoder.encode_text([text])[0], np.float32)
        return self._text_cache[text]

    def negatives(self) -> np.ndarray:
        """Embeddings of the generic phrases the calibrated decision contrasts with, (K, d)."""
        if self._negatives is None:
            self._negatives = np.asarray(self.encoder.encode_text(list(NEGATIVE_PHRASES)), np.float32)
        return self._negatives

    def integrate(self, observation: Mapping, *, segmentation: np.ndarray | None = None) -> None:
        """Fuse one posed RGB-D observation.

        Args:
            observation: ``rgb`` (H, W, 3) uint8, ``depth`` (H, W) metres, ``K`` (3, 3),
                ``cam_to_world`` (4, 4) OpenCV convention.
            segmentation: (H, W) object index per pixel; required in oracle mode (privileged),
                and used by a ground-truth proposer; ignored otherwise.
        """
        rgb, depth, K, pose = frame_from_observation(observation)
        if self.oracle:
            if self._oracle_features is None:
                raise RuntimeError("ConceptMapper: call reset(object_names) before integrate() in oracle mode")
            if segmentation is None:
                raise ValueError("ConceptMapper(oracle=True).integrate: expected the frame's segmentation")
            feats = self._oracle_features(segmentation)
        else:
            if getattr(self.proposer, "privileged", False):
                if segmentation is None:
                    raise ValueError("ConceptMapper: the ground-truth proposer needs the frame's segmentation")
                masks = self.proposer.propose(rgb, depth, K, segmentation_hw=segmentation)
            else:
                masks = self.proposer.propose(rgb, depth, K)
            feats = frame_features(rgb, masks, self.encoder)
        if not self.config.persistent:
            self.map = PointFusionMap(self.encoder.dim, max_depth=self.config.max_depth)
        self.map.integrate(rgb, depth, K, pose, feats)
        self.frames += 1

    def locate(self, text: str) -> QueryResult:
        """Where ``text`` is in the map: regions (best first), or ``found=False`` with a reason."""
        c = self.config
        res = locate(
            self.map, self.text_vector(text), self.negatives(),
            relevancy_threshold=c.relevancy_threshold, voxel_size=c.voxel_size, min_points=c.min_points,
        )
        if c.min_score is None or not res.found:
            return res
        kept = [r for r in res.regions if float(np.median(r.scores_n)) >= c.min_score]
        if kept:
            return dataclasses.replace(res, regions=kept)
        best = max(float(np.median(r.scores_n)) for r in res.regions)
        return dataclasses.replace(
            res, found=False, regions=[], reason=f"the best region scores {best:.2f}, below the encoder's floor {c.min_score:.2f}"
        )

    def locate_many(self, texts: Sequence[str]) -> dict[str, QueryResult]:
        """:meth:`locate` for several descriptions."""
        return {t: self.locate(t) for t in texts}
