"""A loaded map and the perception that questions it: what the viewer's JSON endpoints answer.

:class:`MapQueries` wraps a :class:`~conceptfusion.map.fusion.PointFusionMap` read from a map file
in the agents' :class:`~agents.concept_map.ConceptMapper` (built by
:func:`agents.builtin.make_mapper`), so a text query gets exactly the answer an agent would: the
calibrated decision against generic phrases, regions by voxel connectivity, the encoder's score
floor, and "not found" with its reason. Image queries embed the upload with the encoder's image
tower, click queries take the fused vector at a map point
(:func:`~conceptfusion.map.query.click_query_vector`); both are then located like a text query
(without the text floor, which is calibrated for text).

Answers are JSON-ready dicts; the per-point heat (the paper's relative score) comes as base64
bytes, one per point sent to the browser (0-254, 255 where a point has no concept vector).
"""

from __future__ import annotations

import base64
import os
import threading
import time
from collections import OrderedDict
from pathlib import Path

import numpy as np

from conceptfusion.errors import HarnessError
from conceptfusion.map.fusion import PointFusionMap
from conceptfusion.map.persistence import LOOKUPS, heatmap_colors, load_map
from conceptfusion.map.query import QueryResult, click_query_vector, locate

__all__ = ["BadQueryError", "MapQueries", "DEFAULT_MAX_POINTS", "MAX_IMAGE_BYTES", "check_lookup", "decode_image"]

DEFAULT_MAX_POINTS = 2_000_000
"""Maps with more points are thinned (a fixed random subset) before they go to the browser."""
MAX_IMAGE_BYTES = 16 * 1024 * 1024
"""Largest image upload accepted."""
_MAX_REGIONS = 8
_NO_HEAT = 255


class BadQueryError(HarnessError):
    """A query the viewer cannot answer (empty text, an unreadable image, a click off the map);
    the message says what was expected and what arrived."""


def decode_image(data: bytes) -> np.ndarray:
    """An uploaded image file's bytes (PNG, JPEG, BMP, WebP, TIFF ...) as RGB.

    Shape:
        bytes -> (H, W, 3) uint8.

    Raises:
        BadQueryError: no bytes, too many, or not an image OpenCV can read.
    """
    import cv2

    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise BadQueryError(f"image query: expected the bytes of an image file, got {type(data).__name__}")
    if len(data) == 0:
        raise BadQueryError("image query: expected an image file (PNG or JPEG), got an empty upload")
    if len(data) > MAX_IMAGE_BYTES:
        raise BadQueryError(f"image query: expected at most {MAX_IMAGE_BYTES // 2**20} MB, got {len(data) / 2**20:.1f} MB")
    img = cv2.imdecode(np.frombuffer(bytes(data), np.uint8), cv2.IMREAD_UNCHANGED)
    if img is None or img.size == 0:
        head = bytes(data[:8])
        raise BadQueryError(f"image query: expected a PNG, JPEG, BMP or WebP image, got {len(data)} bytes starting "
                            f"{head!r} that no image decoder reads")
    if img.dtype != np.uint8:
        img = cv2.convertScaleAbs(img, alpha=255.0 / max(float(img.max()), 1.0))
    if img.ndim == 2:
        return np.ascontiguousarray(np.repeat(img[:, :, None], 3, axis=2))
    if img.shape[2] == 4:
        return cv2.cvtColor(img, cv2.COLOR_BGRA2RGB)
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)


def _region_json(region) -> dict:
    return {
        "median": [round(float(v), 4) for v in region.median],
        "aabb_min": [round(float(v), 4) for v in region.aabb_min],
        "aabb_max": [round(float(v), 4) for v in region.aabb_max],
        "score": round(float(region.score), 4),
        "median_score": round(float(np.median(region.scores_n)), 4),
        "num_points": region.num_points,
    }


def check_lookup(lookup) -> str:
    """``lookup`` when it is one of :data:`~conceptfusion.map.persistence.LOOKUPS`; BadQueryError otherwise."""
    if lookup not in LOOKUPS:
        raise BadQueryError(f"lookup: expected one of {', '.join(LOOKUPS)}, got {lookup!r}")
    return lookup


class _ScoredMap:
    """A read-only view of a loaded map for :func:`~conceptfusion.map.query.locate`: its positions
    kept (the map's ``points`` property copies), and the per-point scores of recent query vectors
    remembered, so the generic phrases every query is contrasted with are scored once per map.

    Shape:
        ``points`` (N, 3) float32; ``scores(q)`` (d,) -> (N,) float32.
    """

    def __init__(self, fmap: PointFusionMap, remember: int = 8) -> None:
        self._map, self._remember = fmap, remember
        self.points = fmap.points
        self.feature_dim = fmap.feature_dim
        self.has_feature = fmap.has_feature
        self._scores: OrderedDict[bytes, np.ndarray] = OrderedDict()

    def __len__(self) -> int:
        return len(self._map)

    def features(self, indices) -> np.ndarray:
        return self._map.features(indices)

    def scores(self, query_d) -> np.ndarray:
        key = np.asarray(query_d, np.float32).tobytes()
        if key in self._scores:
            self._scores.move_to_end(key)
        else:
            self._scores[key] = self._map.scores(query_d)
            while len(self._scores) > self._remember:
                self._scores.popitem(last=False)
        return self._scores[key]


class MapQueries:
    """A map file opened for questions.

    Args:
        map_path: a map written by :func:`conceptfusion.map.persistence.save_map`.
        mapper: a :class:`~agents.concept_map.ConceptMapper` whose featurizer matches the map's
            feature dimension (the map replaces the mapper's own).
        encoder_name: how the encoder was named (for messages).
        max_points: points sent to the browser at most (a fixed random subset beyond). They go
            in a fixed random order (:attr:`sent_n`), so that the page can draw any prefix as a
            uniform sample while the view moves.
        lookup: how text queries are asked by default: ``"plain"``
            (:meth:`~agents.concept_map.ConceptMapper.locate`) or ``"present"``
            (:meth:`~agents.concept_map.ConceptMapper.locate_present`, which presumes the named
            object is there, as an agent told to find it does); the map file records its agent's.
        name_only: the name-only last resort of the ``"present"`` lookup.
        notes: lines for the page (e.g. the encoder is not the one the map records).

    Raises:
        MissingFileError, MapFormatError: from loading the map.
        HarnessError: the encoder's dimension differs from the map's.
    """

    def __init__(self, map_path: str | os.PathLike, mapper, *, encoder_name: str, max_points: int = DEFAULT_MAX_POINTS,
                 lookup: str = "plain", name_only: bool = True, notes: tuple[str, ...] = ()):
        if isinstance(max_points, bool) or not isinstance(max_points, int) or max_points < 1:
            raise ValueError(f"max_points: expected an int >= 1, got {max_points!r}")
        self.lookup, self.name_only, self.notes = check_lookup(lookup), bool(name_only), tuple(notes)
        self.path = Path(map_path)
        fmap: PointFusionMap = load_map(self.path)
        if fmap.feature_dim != mapper.featurizer.dim:
            raise HarnessError(
                f"{self.path}: the map's concept vectors have {fmap.feature_dim} dimensions, the encoder "
                f"{encoder_name!r} gives {mapper.featurizer.dim}: open the map with the encoder it was built with "
                "(--encoder)")
        self.map, self.encoder_name = fmap, encoder_name
        self._view = _ScoredMap(fmap)
        mapper.map = self._view  # the mapper only reads it: locate() with the agents' settings
        self.mapper = mapper
        n = len(fmap)
        rng = np.random.default_rng(0)
        # a random order: any prefix is a uniform sample, which the page draws while the view moves
        self.sent_n = rng.choice(n, max_points, replace=False) if n > max_points else rng.permutation(n)
        self._lock = threading.Lock()

    # ------------------------------------------------------------------ what the page draws
    def info(self) -> dict:
        """Map facts for the page: sizes, bounds, encoder and what it can answer."""
        pts = self._view.points
        lo = pts.min(axis=0).tolist() if len(pts) else [0.0, 0.0, 0.0]
        hi = pts.max(axis=0).tolist() if len(pts) else [0.0, 0.0, 0.0]
        # where the camera looks first: the middle 96% of the points that carry concept vectors
        # (a floor or far walls without any would otherwise push the view away)
        has = self.map.has_feature
        sample = pts[has] if has.any() else pts
        sample = sample[:: max(1, len(sample) // 200_000)]
        focus = np.percentile(sample, [2, 98], axis=0).tolist() if len(sample) else [lo, hi]
        return {
            "name": self.path.name, "num_points": len(self.map), "sent_points": int(len(self.sent_n)),
            "with_features": int(self.map.has_feature.sum()), "frames_integrated": int(self.map.frames_integrated),
            "feature_dim": int(self.map.feature_dim), "bounds_min": lo, "bounds_max": hi,
            "focus_min": focus[0], "focus_max": focus[1],
            "encoder": self.encoder_name, "image_queries": hasattr(self.mapper.encoder, "encode_image"),
            "score_floor": self.mapper.config.min_score, "lookup": self.lookup, "notes": list(self.notes),
            "palette": heatmap_colors(np.linspace(0.0, 1.0, 255)).tolist(),
        }

    def points_payload(self) -> bytes:
        """The points sent to the browser: positions then colours, little-endian.

        Shape:
            (M, 3) float32 positions followed by (M, 3) uint8 RGB, M = ``len(self.sent_n)``.
        """
        pts = np.ascontiguousarray(self._view.points[self.sent_n], dtype="<f4")
        rgb = np.ascontiguousarray(self.map.colors[self.sent_n], dtype=np.uint8)
        return pts.tobytes() + rgb.tobytes()

    # ------------------------------------------------------------------ queries
    def _answer(self, kind: str, query: str, res: QueryResult, t0: float, **extra) -> dict:
        rel = res.relative_n[self.sent_n]
        heat = np.full(len(rel), _NO_HEAT, np.uint8)
        ok = np.isfinite(rel)
        heat[ok] = np.clip(np.rint(rel[ok] * 254.0), 0, 254).astype(np.uint8)
        relev = res.relevancy_n[np.isfinite(res.relevancy_n)]
        return {
            "ok": True, "kind": kind, "query": query, "found": bool(res.found), "reason": res.reason,
            "regions": [_region_json(r) for r in res.regions[:_MAX_REGIONS]], "num_regions": len(res.regions),
            "best_relevancy": round(float(relev.max()), 4) if relev.size else None,
            "heat": base64.b64encode(heat.tobytes()).decode("ascii"),
            "server_ms": round((time.perf_counter() - t0) * 1000.0, 2), **extra,
        }

    def _locate_vector(self, vec: np.ndarray) -> QueryResult:
        c = self.mapper.config
        return locate(self._view, vec, self.mapper.negatives(), relevancy_threshold=c.relevancy_threshold,
                      voxel_size=c.voxel_size, min_points=c.min_points)

    def text(self, text, lookup: str | None = None) -> dict:
        """Answer a text query as the map's agent would: ``lookup`` ``"plain"`` or ``"present"``
        (None: the map's own, :attr:`lookup`). A presumed answer says how (``presumed``:
        ``"under_floor"`` or ``"name_only"``), as the agent's record of it does."""
        t0 = time.perf_counter()
        if not isinstance(text, str) or not text.strip():
            raise BadQueryError(f"text query: expected a description such as 'red mug', got {text!r}")
        lookup = self.lookup if lookup is None else check_lookup(lookup)
        text = text.strip()
        with self._lock:
            if lookup == "present":
                res = self.mapper.locate_present(text, name_only=self.name_only)
            else:
                res = self.mapper.locate(text)
            return self._answer("text", text, res, t0, lookup=lookup, presumed=res.extras.get("presumed"))

    def click(self, index) -> dict:
        """Answer the paper's click query at sent point ``index`` (what the page picked)."""
        t0 = time.perf_counter()
        if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index < len(self.sent_n):
            raise BadQueryError(f"click query: expected a point index in [0, {len(self.sent_n)}), got {index!r}")
        point = self._view.points[self.sent_n[index]].astype(np.float64)
        with self._lock:
            try:
                vec = click_query_vector(self._view, point)
            except ValueError as exc:
                raise BadQueryError(str(exc)) from None
            res = self._locate_vector(vec)
            return self._answer("click", f"point ({point[0]:.2f}, {point[1]:.2f}, {point[2]:.2f})", res, t0,
                                clicked=[round(float(v), 4) for v in point])

    def image(self, data: bytes, name: str = "image") -> dict:
        """Answer an image query: the upload embedded by the encoder's image tower."""
        t0 = time.perf_counter()
        if not hasattr(self.mapper.encoder, "encode_image"):
            raise BadQueryError(f"image query: the encoder {self.encoder_name!r} embeds text only; "
                                "open the map with an image-language encoder (--encoder embedded)")
        rgb = decode_image(data)
        with self._lock:
            vec = np.asarray(self.mapper.encoder.encode_image([rgb])[0], np.float32)
            res = self._locate_vector(vec)
            return self._answer("image", f"{name} ({rgb.shape[1]}x{rgb.shape[0]})", res, t0)
