"""Online ConceptFusion mapping for agents: frames in, 3D answers to text queries out.

A :class:`ConceptMapper` owns a :class:`~conceptfusion.map.fusion.PointFusionMap` and a
:class:`~conceptfusion.perception.featurizer.FrameFeaturizer` that turns each posed RGB-D frame
into pixel-aligned features (paper eqs. 3-6) fused into the map (eqs. 1-2). Agents ask it where
a described object is (:meth:`ConceptMapper.locate`) and get a 3D region or an explicit "not
found".

Perception is the featurizer's business (built by
:func:`~conceptfusion.perception.featurizer.make_featurizer`): perceived (mask proposals and an
encoder) or a privileged oracle (ground-truth segmentation labelled with name embeddings, or with
orthogonal codes and ground-truth grounding of descriptions, ``oracle-open``; both need the
simulator's segmentation, passed explicitly, and the labels' names or phrases at
:meth:`ConceptMapper.reset`, which :func:`privileged_labels` reads from an environment's info).
:attr:`ConceptMapper.privileged` says which; results built on a privileged map must say so.

A single-frame (2.5D) agent uses the same mapper with ``persistent=False``: every frame
replaces the map, so answers come from the current view only.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from types import MappingProxyType
from typing import Iterable, Mapping, Sequence

import numpy as np

from conceptfusion.frames import RGBDFrame
from conceptfusion.map.fusion import PointFusionMap
from conceptfusion.map.query import NEGATIVE_PHRASES, QueryResult, locate, relative_scores, relevancy, vocabulary_margins
from conceptfusion.map.regions import Region, SupportTest
from conceptfusion.perception.featurizer import FrameFeaturizer

__all__ = ["ConceptMapper", "MapperConfig", "frame_from_observation", "privileged_labels"]


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
    drop_support: bool = True
    """Regions lose the horizontal surface they stand on when they have bled into it (the table
    rim around a mug's base; see :func:`conceptfusion.map.regions.drop_support`)."""
    min_score: float | None = None
    """Also require the best region's median cosine score to reach this (None: no such test).
    Generic negatives do not reject a near-miss ("brown bottle" for "the black bottle" scores
    0.70 with MiniLM text features, "object" 0.35), so an encoder-specific floor does: exact
    names score >= 0.9 with oracle features."""


def frame_from_observation(observation: Mapping | RGBDFrame, segmentation: np.ndarray | None = None) -> RGBDFrame:
    """The posed RGB-D frame in an observation (``rgb``, ``depth``, ``K``, ``cam_to_world``).

    An :class:`~conceptfusion.frames.RGBDFrame` is returned as is (with ``segmentation`` when
    given). Depth becomes float32, ``K`` and the pose float64.

    Shape:
        returns a frame of rgb (H, W, 3) uint8, depth (H, W) float32, K (3, 3),
        cam_to_world (4, 4), segmentation (H, W) int or None.

    Raises:
        KeyError: a key of the posed frame is missing.
    """
    if isinstance(observation, RGBDFrame):
        return observation if segmentation is None else dataclasses.replace(observation, segmentation=segmentation)
    missing = [k for k in ("rgb", "depth", "K", "cam_to_world") if k not in observation]
    if missing:
        raise KeyError(f"observation: expected a posed RGB-D frame with keys rgb, depth, K, cam_to_world; missing {missing}")
    return RGBDFrame.from_observation({
        "rgb": np.asarray(observation["rgb"]),
        "depth": np.asarray(observation["depth"], np.float32),
        "K": np.asarray(observation["K"], np.float64),
        "cam_to_world": np.asarray(observation["cam_to_world"], np.float64),
    }, segmentation)


def privileged_labels(mapper: "ConceptMapper", info: Mapping | None) -> dict:
    """The keyword arguments of :meth:`ConceptMapper.reset` from an environment's ``info``:
    ``object_names`` and ``object_phrases`` by segmentation id (object index) when the mapper is
    privileged and ``info`` has them; empty otherwise (no ground truth is read then).

    Shape:
        ``info["object_names"]`` (n,) str, ``info["object_phrases"]`` (n,) lists of str ->
        ``{"object_names": {i: name}, "object_phrases": {i: phrases}}`` (either may be missing).
    """
    if not mapper.privileged or not info:
        return {}
    out = {}
    if "object_names" in info:
        out["object_names"] = dict(enumerate(info["object_names"]))
    if "object_phrases" in info:
        out["object_phrases"] = dict(enumerate(info["object_phrases"]))
    return out


class ConceptMapper:
    """Fuse observations into a concept map and answer text queries.

    Args:
        featurizer: the perception (:func:`~conceptfusion.perception.featurizer.make_featurizer`);
            its text embeddings answer the queries.
        config: see :class:`MapperConfig` (``min_score`` is taken as given; builders pass the
            featurizer's ``score_floor``, see :func:`agents.builtin.make_mapper`).
    """

    def __init__(self, featurizer: FrameFeaturizer, config: MapperConfig = MapperConfig()) -> None:
        missing = [a for a in ("features", "encode_text", "reset", "dim") if not hasattr(featurizer, a)]
        if missing:
            raise TypeError(f"ConceptMapper: expected a frame featurizer (make_featurizer(...)); "
                            f"{type(featurizer).__name__} has no {', '.join(missing)}")
        self.featurizer, self.config = featurizer, config
        self._text_cache: dict[str, np.ndarray] = {}
        self._negatives = None
        self._vocabulary_kd = None
        self.map = PointFusionMap(featurizer.dim, max_depth=config.max_depth)
        self.frames = 0
        self._answers: dict[str, QueryResult] = {}

    @property
    def privileged(self) -> bool:
        """True when the map is built from ground truth (oracle features or a ground-truth proposer)."""
        return bool(self.featurizer.privileged)

    @property
    def encoder(self):
        """The featurizer's encoder (image queries embed crops with it)."""
        return self.featurizer.encoder

    def reset(self, object_names: Mapping[int, str] | None = None,
              object_phrases: Mapping[int, Iterable[str]] | None = None) -> None:
        """Start an empty map. Oracle perception needs the names of the segmentation ids
        (``oracle``) or the phrases each answers to (``oracle-open``); both go to the
        featurizer's ``reset``. Cached text embeddings are dropped when the featurizer's
        depend on the scene (``scene_dependent_text``)."""
        self.map = PointFusionMap(self.featurizer.dim, max_depth=self.config.max_depth)
        self.frames = 0
        self._answers.clear()
        if getattr(self.featurizer, "scene_dependent_text", False):
            self._text_cache.clear()
            self._negatives = None
            self._vocabulary_kd = None
        if object_phrases is None:
            self.featurizer.reset(object_names)
        else:
            self.featurizer.reset(object_names, object_phrases)

    @property
    def answers(self) -> Mapping[str, QueryResult]:
        """The latest answer of :meth:`locate` to each description asked since the last
        :meth:`reset` (a read-only view, for replays and reports; the agent's decisions never read it)."""
        return MappingProxyType(self._answers)

    def text_vector(self, text: str) -> np.ndarray:
        """The featurizer's unit embedding of ``text`` (cached)."""
        if not isinstance(text, str) or not text.strip():
            raise ValueError(f"query: expected a non-empty description, got {text!r}")
        if text not in self._text_cache:
            self._text_cache[text] = np.asarray(self.featurizer.encode_text([text])[0], np.float32)
        return self._text_cache[text]

    def negatives(self) -> np.ndarray:
        """Embeddings of the generic phrases the calibrated decision contrasts with, (K, d)."""
        if self._negatives is None:
            self._negatives = np.asarray(self.featurizer.encode_text(list(NEGATIVE_PHRASES)), np.float32)
        return self._negatives

    @property
    def vocabulary(self) -> tuple[str, ...]:
        """The names the featurizer's image side was trained to tell apart (its ``vocabulary``;
        empty for the oracles and for encoders that record none)."""
        return tuple(getattr(self.featurizer, "vocabulary", ()) or ())

    def identify(self, text: str, candidates: Sequence[Region]) -> QueryResult:
        """Which of ``candidates`` ``text`` names, for a caller that knows it is one of them
        (an instruction names an object on the table, and the candidates are the table's objects):
        the candidates ordered by :func:`~conceptfusion.map.query.vocabulary_margins` against
        the featurizer's :attr:`vocabulary`, best first, each region's ``scores_n`` its points'
        scores for ``text``. ``found`` is False only when there is no candidate. ``extras``:
        ``identified`` (``"vocabulary"``) and ``margins``, best first. ``relevancy_n`` is against
        the generic phrases, as :meth:`locate` gives it.

        Shape:
            candidates: regions of this map (with ``indices_n``).

        Raises:
            ValueError: the featurizer has no vocabulary (see :attr:`vocabulary`), or a
                candidate has no point indices of this map.
        """
        if not self.vocabulary:
            raise ValueError(f"identify: the featurizer ({type(self.featurizer).__name__}) records no vocabulary "
                             "of trained names; use locate or locate_present")
        if self._vocabulary_kd is None:
            self._vocabulary_kd = np.asarray(self.featurizer.encode_text(list(self.vocabulary)), np.float32)
        q = self.text_vector(text)
        both = self.map.scores_many(np.concatenate([q[None], self.negatives()]))
        scores, relev = both[0], relevancy(both[0], both[1:])
        margins = vocabulary_margins(self.map, q, self._vocabulary_kd, candidates)
        order = np.argsort(-margins, kind="stable")
        regions = [Region(points_n3=candidates[i].points_n3, scores_n=scores[candidates[i].indices_n],
                          indices_n=candidates[i].indices_n) for i in order]
        res = QueryResult(bool(regions), regions, scores, relative_scores(scores), relev,
                          "" if regions else "no candidate objects to choose from",
                          {"identified": "vocabulary", "margins": [float(margins[i]) for i in order]})
        self._answers[text] = res
        return res

    def integrate(self, observation: Mapping | RGBDFrame, *, segmentation: np.ndarray | None = None) -> None:
        """Fuse one posed RGB-D frame.

        Args:
            observation: an :class:`~conceptfusion.frames.RGBDFrame`, or an observation with
                ``rgb`` (H, W, 3) uint8, ``depth`` (H, W) metres, ``K`` (3, 3),
                ``cam_to_world`` (4, 4) OpenCV convention.
            segmentation: (H, W) object index per pixel (privileged); required by oracle
                perception and a ground-truth proposer, ignored otherwise.
        """
        frame = frame_from_observation(observation, segmentation)
        feats = self.featurizer.features(frame)
        if not self.config.persistent:
            self.map = PointFusionMap(self.featurizer.dim, max_depth=self.config.max_depth)
        self.map.integrate(frame.rgb, frame.depth, frame.K, frame.cam_to_world, feats)
        self.frames += 1

    def locate(self, text: str, *, floor: bool = True, contrast: bool = True) -> QueryResult:
        """Where ``text`` is in the map: regions (best first), or ``found=False`` with a reason.

        ``floor=False`` leaves out the encoder's score floor (``config.min_score``): regions
        need only beat the generic phrases, for callers that know the object is there.
        ``contrast=False`` (with ``floor=False``) leaves out the generic phrases as well: the
        points scoring highest for ``text`` form the regions whatever else they resemble, for a
        name the encoder may never have learned (it scores below "object" everywhere)."""
        if not contrast and floor:
            raise ValueError("locate: contrast=False needs floor=False (the floor is calibrated on contrasted answers)")
        res = self._locate(text, floor, contrast)
        self._answers[text] = res
        return res

    def locate_present(self, text: str, *, name_only: bool = True, candidates: Sequence[Region] | None = None) -> QueryResult:
        """:meth:`locate` for an object the caller knows is there (an instruction or a question
        names it): the floored answer when it finds ``text``; else, given ``candidates`` (the
        things the object must be one of, such as the table's objects) and a featurizer with a
        :attr:`vocabulary`, the candidate :meth:`identify` ranks first; else the best region
        without the floor (it must still beat the generic phrases); else, with ``name_only``, the
        region that scores highest for ``text`` alone (``contrast=False``); else the floored
        answer. ``extras["presumed"]`` says which: absent for the floored answer,
        ``"identified"``, ``"under_floor"`` or ``"name_only"``, with ``extras["passed_over"]`` the
        reasons of the answers passed over. :attr:`answers` records the answer returned, not the
        last one asked on the way."""
        answer = self.locate(text)
        if not answer.found:
            reasons = [answer.reason]
            if candidates and self.vocabulary:
                ident = self.identify(text, candidates)
                answer = dataclasses.replace(ident, extras={**ident.extras, "presumed": "identified", "passed_over": reasons})
                self._answers[text] = answer
                return answer
            loose = self.locate(text, floor=False)
            bare = None
            if not loose.found:
                reasons.append(loose.reason)
                bare = self.locate(text, floor=False, contrast=False) if name_only else None
            if loose.found:
                answer = dataclasses.replace(loose, extras={**loose.extras, "presumed": "under_floor", "passed_over": reasons})
            elif bare is not None and bare.found:
                answer = dataclasses.replace(bare, extras={**bare.extras, "presumed": "name_only", "passed_over": reasons})
        self._answers[text] = answer
        return answer

    def _locate(self, text: str, floor: bool = True, contrast: bool = True) -> QueryResult:
        c = self.config
        negatives = self.negatives() if contrast else np.zeros((0, self.featurizer.dim), np.float32)
        res = locate(
            self.map, self.text_vector(text), negatives,
            relevancy_threshold=c.relevancy_threshold, voxel_size=c.voxel_size, min_points=c.min_points,
            support=SupportTest() if c.drop_support else None,
        )
        if c.min_score is None or not floor or not res.found:
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
