"""Online ConceptFusion mapping: posed RGB-D frames in, 3D answers to text queries out.

A :class:`ConceptMapper` owns a :class:`~conceptfusion.map.fusion.PointFusionMap` and a
:class:`~conceptfusion.perception.featurizer.FrameFeaturizer` that turns each posed RGB-D frame
into pixel-aligned features (paper eqs. 3-6) fused into the map (eqs. 1-2). Callers (a
researcher's script, ``cfharness map``, the agents) ask it where a described object is
(:meth:`ConceptMapper.locate`) and get a 3D region or an explicit "not found".
:func:`make_mapper` builds one with the encoder's calibrated score floor, the one public way to
build a mapper (``from conceptfusion import make_mapper``); :meth:`ConceptMapper.save` writes
its map with what the viewer needs to ask it the same way.

Perception is the featurizer's business (built by
:func:`~conceptfusion.perception.featurizer.make_featurizer`): perceived (mask proposals and an
encoder) or a privileged oracle (ground-truth segmentation labelled with name embeddings, or with
orthogonal codes and ground-truth grounding of descriptions, ``oracle-open``; both need the
simulator's segmentation, passed explicitly, and the labels' names or phrases at
:meth:`ConceptMapper.reset`, which the agents read from an environment's info).
:attr:`ConceptMapper.privileged` says which; results built on a privileged map must say so.

A single-frame (2.5D) agent uses the same mapper with ``persistent=False``: every frame
replaces the map, so answers come from the current view only.

A matched map-free twin uses it with ``semantic_views=k``: the map keeps every frame's geometry
(what occupancy grids, frontiers, table extents and push corridors read) but no concept vectors;
each of the last ``k`` frames keeps its own, and a query is answered on each of those frames
alone, the best single-frame answer winning. The twin sees the same views, explores and plans on
the same geometry and decides by the same rules; it differs from the map agent only in that its
semantics are not fused across views.
"""

from __future__ import annotations

import dataclasses
import os
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Iterable, Mapping, Sequence

import numpy as np
from scipy.spatial import cKDTree

from conceptfusion.frames import RGBDFrame
from conceptfusion.map.fusion import PointFusionMap
from conceptfusion.map.query import (NEGATIVE_PHRASES, QueryResult, locate, regions_batch, relative_scores, relevancy,
                                     vocabulary_margins)
from conceptfusion.map.regions import Region, SupportTest
from conceptfusion.names import did_you_mean
from conceptfusion.perception.featurizer import FrameFeaturizer, PerceptionSpec, make_featurizer, score_floor_for
from conceptfusion.perception.registry import DEFAULT_ENCODER

__all__ = ["ConceptMapper", "MapperConfig", "frame_from_observation", "make_mapper"]


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
    semantic_views: int = 0
    """0: concept vectors are fused into the map (ConceptFusion). ``k >= 1``: the matched map-free
    twin (see the module docstring): the map fuses geometry only, each of the last ``k``
    integrated frames keeps its own concept vectors, and answers come from the best single frame,
    carried over to the map's points within ``1.5 * voxel_size`` of that frame's (so regions,
    scores and point indices refer to :attr:`ConceptMapper.map` as in the fused case). The search
    twin keeps 1 (its current frame); the pusher twin keeps its scan (it starts a new map every
    step)."""
    min_score: float | None = None
    """Also require the best region's median cosine score to reach this (None: no such test).
    Generic negatives do not reject a near-miss ("brown bottle" for "the black bottle" scores
    0.70 with MiniLM text features, "object" 0.35), so an encoder-specific floor does: exact
    names score >= 0.9 with oracle features."""

    def __post_init__(self) -> None:
        if isinstance(self.semantic_views, bool) or not isinstance(self.semantic_views, int) or self.semantic_views < 0:
            raise ValueError(f"semantic_views: expected an integer >= 0, got {self.semantic_views!r}")


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


class ConceptMapper:
    """Fuse observations into a concept map and answer text queries.

    Args:
        featurizer: the perception (:func:`~conceptfusion.perception.featurizer.make_featurizer`);
            its text embeddings answer the queries.
        config: see :class:`MapperConfig` (``min_score`` is taken as given; builders pass the
            featurizer's calibrated floor, see :func:`make_mapper`).
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
        self._views: deque[PointFusionMap] = deque(maxlen=max(1, config.semantic_views))
        """Single-frame maps of the last ``semantic_views`` frames (the twin's semantics; empty when fused)."""
        self.provenance: dict = {}
        """How the mapper was made, for a saved map's ``meta`` (see
        :data:`conceptfusion.map.persistence.META_KEYS`): ``encoder``, ``proposer``, ``setting``
        when :func:`make_mapper` built it; empty otherwise."""
        self.lookup_used: dict = {"lookup": "plain"}
        """How callers asked the map: ``{"lookup": "plain"}`` until :meth:`locate_present` is first
        called, then ``{"lookup": "present", "name_only": ...}`` (a saved map records it, and the
        viewer asks the same way)."""

    def meta(self) -> dict:
        """What a saved map records of how this mapper was made and is asked (its ``meta``, see
        :data:`conceptfusion.map.persistence.META_KEYS`): ``encoder``, ``proposer`` and
        ``setting`` from :attr:`provenance` (when :func:`make_mapper` built it), ``min_score`` the
        floor applied (None: none) and :attr:`lookup_used`. ``cfharness view`` opens a map with them."""
        meta = {k: v for k, v in self.provenance.items() if k in ("encoder", "proposer", "setting")}
        meta["min_score"] = None if self.config.min_score is None else float(self.config.min_score)
        meta.update(self.lookup_used)
        return meta

    def save(self, path: str | os.PathLike) -> Path:
        """Write the map to ``path`` (``.npz``, atomically) with :meth:`meta`, so that ``cfharness
        view PATH`` asks it with this mapper's encoder, floor and lookup; returns the path.

        Example::

            from conceptfusion import load_map, make_mapper

            mapper = make_mapper("color")
            mapper.save("runs/mine/scene.map.npz")   # then: cfharness view runs/mine/scene.map.npz
            assert len(load_map("runs/mine/scene.map.npz")) == len(mapper.map)
        """
        from conceptfusion.map.persistence import save_map

        return save_map(self.map, path, meta=self.meta())

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
        self._views.clear()
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
        view = self.map
        if self.config.semantic_views and self._views:
            margins, view = self._view_margins(q, candidates)
        else:
            margins = vocabulary_margins(self.map, q, self._vocabulary_kd, candidates)
        both = view.scores_many(np.concatenate([q[None], self.negatives()]))
        scores, relev = both[0], relevancy(both[0], both[1:])
        if view is not self.map:
            near, nearest = self._near_view(view)
            scores, relev = (np.where(near, v[np.maximum(nearest, 0)], np.nan).astype(np.float32) for v in (scores, relev))
        order = np.argsort(-margins, kind="stable")
        regions = [Region(points_n3=candidates[i].points_n3, scores_n=scores[candidates[i].indices_n],
                          indices_n=candidates[i].indices_n) for i in order]
        res = QueryResult(bool(regions), regions, scores, relative_scores(scores), relev,
                          "" if regions else "no candidate objects to choose from",
                          {"identified": "vocabulary", "margins": [float(margins[i]) for i in order]})
        self._answers[text] = res
        return res

    def _view_margins(self, q: np.ndarray, candidates: Sequence[Region]) -> tuple[np.ndarray, PointFusionMap]:
        """:func:`~conceptfusion.map.query.vocabulary_margins` of map regions ``candidates`` on
        each kept frame alone (a candidate's points there: the frame's points within ``1.5 *
        voxel_size`` of it), and the frame whose best candidate has the highest margin.

        Shape: -> (R,) float64 (``-inf`` for a candidate the frame does not show), the frame's map."""
        r = 1.5 * self.config.voxel_size
        sizes = [len(c.points_n3) for c in candidates]
        labels = np.repeat(np.arange(len(candidates)), sizes)
        tree = cKDTree(np.concatenate([c.points_n3 for c in candidates])) if sum(sizes) else None
        best: tuple[np.ndarray, PointFusionMap] | None = None
        for view in self._views:
            margins = np.full(len(candidates), -np.inf)
            if tree is not None and len(view):
                d, j = tree.query(view.points, distance_upper_bound=r)
                lab = np.where(np.isfinite(d), labels[np.minimum(j, len(labels) - 1)], -1)
                shown = [i for i in range(len(candidates)) if np.any(lab == i)]
                if shown:
                    parts = [Region(points_n3=view.points[lab == i], scores_n=np.zeros(0, np.float32), indices_n=np.flatnonzero(lab == i))
                             for i in shown]
                    margins[shown] = vocabulary_margins(view, q, self._vocabulary_kd, parts)
            if best is None or margins.max(initial=-np.inf) > best[0].max(initial=-np.inf):
                best = (margins, view)
        return best

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
        if self.config.semantic_views:
            view = PointFusionMap(self.featurizer.dim, max_depth=self.config.max_depth)
            view.integrate(frame.rgb, frame.depth, frame.K, frame.cam_to_world, feats)
            self._views.append(view)
            feats = None
        self.map.integrate(frame.rgb, frame.depth, frame.K, frame.cam_to_world, feats)
        self.frames += 1

    @property
    def described_n(self) -> np.ndarray:
        """Which map points carry concept vectors: fused ones (``map.has_feature``), or for a twin
        (``semantic_views``) the points near a kept frame's featured points. Shape: (N,) bool."""
        if not self.config.semantic_views:
            return self.map.has_feature
        featured = [view.points[view.has_feature] for view in self._views]
        return self._near(np.concatenate(featured) if featured else np.zeros((0, 3)))[0]

    def _near_view(self, view: PointFusionMap) -> tuple[np.ndarray, np.ndarray]:
        """Map points within ``1.5 * voxel_size`` of ``view``'s points, and the index of the nearest
        such view point for each. Shape: (N,) bool, (N,) int64 (-1 where not near)."""
        return self._near(view.points)

    def _near(self, vpts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Map points within ``1.5 * voxel_size`` of points ``vpts``, and the index into ``vpts`` of
        the nearest for each. Shape: ``vpts`` (M, 3) -> (N,) bool, (N,) int64 (-1 where not near)."""
        r = 1.5 * self.config.voxel_size
        pts = self.map.points
        near = np.zeros(len(pts), bool)
        nearest = np.full(len(pts), -1, np.int64)
        if len(vpts) == 0 or len(pts) == 0:
            return near, nearest
        lo, hi = vpts.min(axis=0) - r, vpts.max(axis=0) + r
        box = np.flatnonzero(np.all((pts >= lo) & (pts <= hi), axis=1))
        if box.size:
            d, j = cKDTree(vpts).query(pts[box], distance_upper_bound=r)
            ok = np.isfinite(d)
            near[box[ok]] = True
            nearest[box[ok]] = j[ok]
        return near, nearest

    def _to_map(self, view: PointFusionMap, res: QueryResult) -> QueryResult:
        """A single frame's answer carried over to the map's points (see ``semantic_views``)."""
        near, nearest = self._near_view(view)

        def carry(values_v: np.ndarray) -> np.ndarray:
            out = np.full(len(self.map), np.nan, np.float32)
            out[near] = values_v[nearest[near]]
            return out

        regions = []
        r = 1.5 * self.config.voxel_size
        scores = carry(res.scores_n)
        for reg in res.regions:
            mine = np.zeros(len(view), bool)
            mine[reg.indices_n] = True
            idx = np.flatnonzero(near & mine[np.maximum(nearest, 0)])
            if idx.size == 0:  # the map merged this region's points farther away: the map's points near the region
                d, _ = cKDTree(reg.points_n3).query(self.map.points, distance_upper_bound=r)
                idx = np.flatnonzero(np.isfinite(d))
            if idx.size:
                regions.append(Region(points_n3=self.map.points[idx], scores_n=scores[idx], indices_n=idx))
        found = res.found and bool(regions)
        return QueryResult(found, regions if found else [], scores, carry(res.relative_n), carry(res.relevancy_n),
                           res.reason if found or not res.found else "no map point near the frame's answer", dict(res.extras))

    def _best_view(self, answer_on) -> QueryResult:
        """``answer_on(view) -> (QueryResult, key)`` on every kept frame alone; the answer of the
        frame with the highest key (found answers first), carried over to the map."""
        if not self._views:
            return answer_on(self.map)[0]
        answers = [(answer_on(view), view) for view in self._views]
        (res, _), view = max(answers, key=lambda a: (a[0][0].found, a[0][1]))
        return self._to_map(view, res)

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
        self.lookup_used = {"lookup": "present", "name_only": bool(name_only)}
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
        if not self.config.semantic_views:
            return self._locate_on(self.map, text, floor, contrast)

        def answer_on(view):
            res = self._locate_on(view, text, floor, contrast)
            if res.found:
                return res, float(np.median(res.best.scores_n))
            return res, float(np.nanmax(res.scores_n)) if np.isfinite(res.scores_n).any() else -np.inf

        return self._best_view(answer_on)

    def _locate_on(self, map_: PointFusionMap, text: str, floor: bool, contrast: bool) -> QueryResult:
        c = self.config
        negatives = self.negatives() if contrast else np.zeros((0, self.featurizer.dim), np.float32)
        res = locate(map_, self.text_vector(text), negatives, **self._query_settings())
        if c.min_score is None or not floor or not res.found:
            return res
        kept = self._above_floor(res.regions)
        if kept:
            return dataclasses.replace(res, regions=kept)
        best = max(float(np.median(r.scores_n)) for r in res.regions)
        return dataclasses.replace(
            res, found=False, regions=[], reason=f"the best region scores {best:.2f}, below the encoder's floor {c.min_score:.2f}"
        )

    def _query_settings(self) -> dict:
        """The keyword arguments of the map queries (:func:`~conceptfusion.map.query.locate`) from the config."""
        c = self.config
        return dict(relevancy_threshold=c.relevancy_threshold, voxel_size=c.voxel_size, min_points=c.min_points,
                    support=SupportTest() if c.drop_support else None)

    def _above_floor(self, regions: Sequence[Region]) -> list[Region]:
        """``regions`` whose median score reaches the score floor (``config.min_score``; all without one)."""
        floor = self.config.min_score
        return [r for r in regions if floor is None or float(np.median(r.scores_n)) >= floor]

    def present(self, texts: Sequence[str]) -> dict[str, Region]:
        """The best region of every text :meth:`locate` finds (above the score floor), in one
        batch over a fused map (:func:`~conceptfusion.map.query.regions_batch`: the hardest
        negative taken once, texts no point scores above it for skipped): what listing the
        objects a map holds needs, without the per-point arrays of full answers. Texts not found
        are left out; nothing is added to :attr:`answers`."""
        texts = list(dict.fromkeys(texts))
        if self.config.semantic_views or not texts:
            found = {t: self.locate(t) for t in texts}
            return {t: r.best for t, r in found.items() if r.found}
        regions = regions_batch(self.map, np.stack([self.text_vector(t) for t in texts]), self.negatives(),
                                **self._query_settings())
        kept = {t: self._above_floor(regs) for t, regs in zip(texts, regions)}
        return {t: regs[0] for t, regs in kept.items() if regs}

    def locate_many(self, texts: Sequence[str]) -> dict[str, QueryResult]:
        """:meth:`locate` for several descriptions."""
        return {t: self.locate(t) for t in texts}


_CONFIG_FIELDS = tuple(f.name for f in dataclasses.fields(MapperConfig))


def make_mapper(
    perception: PerceptionSpec | str | FrameFeaturizer = DEFAULT_ENCODER, proposer: str = "rgbd", *,
    setting: str = "tabletop", **config,
) -> ConceptMapper:
    """A :class:`ConceptMapper` with the encoder's calibrated score floor for ``setting`` on.

    The floor (``config.min_score``) is what turns "the best region beats the generic phrases"
    into "the object is here": without it a relative answer is found even for an object that is
    absent. It is the featurizer's, for ``setting`` (``"tabletop"``, ``"household"`` or
    ``"search"``, see :func:`~conceptfusion.perception.featurizer.score_floor_for`: the v2 tower
    ships floors calibrated per setting).

    Args:
        perception: an encoder spec string (``"embedded"``, ``"color"``, ``"hf:..."``,
            ``"onnx:DIR"``, a registered name; ``proposer`` then names the mask proposer), a
            :class:`~conceptfusion.perception.featurizer.PerceptionSpec`, or a featurizer
            already built (the map then records no encoder).
        proposer: the mask proposer for an encoder spec string.
        setting: which calibrated floor applies.
        config: fields of :class:`MapperConfig` (``max_depth``, ``persistent``,
            ``semantic_views``, ``voxel_size`` ...). ``min_score`` given here replaces the
            calibrated floor (None: no floor).

    Example::

        from conceptfusion import RGBDFrame, make_mapper

        mapper = make_mapper("color")            # any --encoder spec; the default is "embedded"
        mapper.integrate(RGBDFrame(rgb=rgb_hw3, depth=depth_hw, K=K_33, cam_to_world=pose_44))
        result = mapper.locate("red box")        # regions, relevancy, found or not (with the reason)
        mapper.save("scene.map.npz")             # then: cfharness view scene.map.npz

    Raises:
        UnknownNameError: unknown encoder or proposer name (naming the nearest valid ones).
        ValueError: an unknown setting.
        TypeError: an unknown ``config`` field (naming the nearest ones).
    """
    unknown = [k for k in config if k not in _CONFIG_FIELDS]
    if unknown:
        raise TypeError(f"make_mapper: unknown mapper setting {unknown[0]!r}{did_you_mean(unknown[0], _CONFIG_FIELDS)} "
                        f"(MapperConfig fields: {', '.join(_CONFIG_FIELDS)})")
    provenance = {"setting": setting}
    if isinstance(perception, (str, PerceptionSpec)):
        spec = PerceptionSpec.parse(perception, proposer=proposer) if isinstance(perception, str) else perception
        featurizer = make_featurizer(spec)
        provenance.update(encoder=spec.encoder, proposer=spec.proposer)
    else:
        featurizer = perception
    floor = score_floor_for(featurizer, setting)
    mapper = ConceptMapper(featurizer, MapperConfig(**{"min_score": floor, **config}))
    mapper.provenance = provenance
    return mapper
