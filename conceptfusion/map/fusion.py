"""PointFusion map with concept vectors (Keller et al. 2013 as ConceptFusion uses it, eqs. 1-2).

The map is an unordered set of points, each with a position, a normal, a colour, a
confidence count and a concept vector. A frame is fused by **projective data association**:
every map point is projected into the new frame; a pixel merges into the point that
projects onto it when the point lies within ``dist_th`` metres of the pixel's back-projected
vertex and their normals differ by less than ``angle_th_deg`` (when several points project
onto one pixel, the most confident wins, then the nearest). Merging is a confidence-weighted
running mean of position, normal, colour and feature (eq. 1) and the confidence accumulates
(eq. 2), with the per-pixel confidence ``alpha = exp(-gamma^2 / (2 sigma^2))``
(:func:`conceptfusion.cameras.radial_confidence`). A valid pixel that merges with no point
becomes a new point. Invalid depth (NaN, inf, <= 0, beyond ``max_depth``) and pixels without
a normal are skipped, never fused.

Features live in a :class:`~conceptfusion.map.feature_store.FeatureStore`; pixels without a
feature (zero vector) update geometry only and never dilute a point's feature.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from conceptfusion.map import _kernels
from conceptfusion.map._association import associate
from conceptfusion.map._threads import run_ranges
from conceptfusion._checks import as_array, as_float_array
from conceptfusion.cameras import check_intrinsics, check_pose, radial_confidence
from conceptfusion.errors import DtypeError, ShapeError
from conceptfusion.map.dense import palette_from_dense
from conceptfusion.map.feature_store import FeatureStore
from conceptfusion.perception.features import PixelFeatures

__all__ = ["PointFusionMap", "FusionConfig", "IntegrationStats"]

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class FusionConfig:
    """Parameters of :class:`PointFusionMap` (defaults: the paper's / Keller et al.'s)."""

    dist_th: float = 0.05
    """Largest distance (m) between a map point and a pixel's vertex for them to merge."""
    angle_th_deg: float = 20.0
    """Largest angle (degrees) between their normals for them to merge."""
    sigma: float = 0.6
    """Width of the radial confidence ``exp(-gamma^2 / (2 sigma^2))``."""
    max_depth: float = math.inf
    """Depth beyond this (m) is treated as invalid."""
    slots: int = 8
    """Distinct frame features a point keeps exactly (see FeatureStore)."""

    def __post_init__(self) -> None:
        if not self.dist_th > 0:
            raise ValueError(f"dist_th: expected a positive distance, got {self.dist_th}")
        if not 0 < self.angle_th_deg <= 180:
            raise ValueError(f"angle_th_deg: expected a value in (0, 180], got {self.angle_th_deg}")
        if not self.sigma > 0:
            raise ValueError(f"sigma: expected a positive value, got {self.sigma}")
        if not self.max_depth > 0:
            raise ValueError(f"max_depth: expected a positive depth, got {self.max_depth}")
        if int(self.slots) != self.slots or self.slots < 1:
            raise ValueError(f"slots: expected a positive integer, got {self.slots}")


@dataclass(frozen=True)
class IntegrationStats:
    """What one :meth:`PointFusionMap.integrate` call did."""

    merged: int
    """Pixels fused into existing points."""
    covered: int
    """Pixels next to a compatible map point, neither fused nor added (map density kept)."""
    added: int
    """Pixels that became new points."""
    skipped: int
    """Pixels skipped for invalid depth or normal."""
    num_points: int
    """Map size afterwards."""


_GEO_COLS = 10
_MERGE_CHUNK = 1 << 13  # fewest matched points per thread in the geometry merge
_LARGE_PALETTE = 4096  # distinct features in one frame beyond which integrate() warns about the bank
_POS, _NRM, _RGB, _CONF = slice(0, 3), slice(3, 6), slice(6, 9), 9


@lru_cache(maxsize=8)
def _confidence(h: int, w: int, k_key: tuple[float, ...], sigma: float) -> np.ndarray:
    return radial_confidence(h, w, np.array(k_key).reshape(3, 3), sigma=sigma).ravel()


class PointFusionMap:
    """A point map whose points carry concept vectors, fused frame by frame.

    Args:
        feature_dim: dimension ``d`` of the concept vectors.
        dist_th, angle_th_deg, sigma, max_depth, slots: see :class:`FusionConfig`.

    Shape:
        positions (N, 3) float32 world metres; normals (N, 3) unit; colours (N, 3) uint8;
        confidence (N,) float32; features (N, d) float32 unit length (zero if none).
    """

    def __init__(
        self,
        feature_dim: int,
        *,
        dist_th: float = 0.05,
        angle_th_deg: float = 20.0,
        sigma: float = 0.6,
        max_depth: float = math.inf,
        slots: int = 8,
    ) -> None:
        if int(feature_dim) != feature_dim or feature_dim <= 0:
            raise ValueError(f"feature_dim: expected a positive integer, got {feature_dim}")
        self.config = FusionConfig(dist_th, angle_th_deg, sigma, max_depth, slots)
        self.feature_dim = int(feature_dim)
        self._n = 0
        # One row per point: position (3), normal (3), colour 0-255 (3), confidence (1).
        # Packed so that association and merging gather and scatter each point once.
        self._geo = np.zeros((0, _GEO_COLS), np.float32)
        self._store = FeatureStore(self.feature_dim, slots)
        self.frames_integrated = 0

    # ------------------------------------------------------------------ size
    def __len__(self) -> int:
        return self._n

    def _reserve(self, extra: int) -> None:
        need = self._n + extra
        cap = len(self._geo)
        if need <= cap:
            return
        new_cap = max(need, 2 * cap + 4096)
        geo = np.empty((new_cap, _GEO_COLS), np.float32)  # rows past _n are set on append
        geo[: self._n] = self._geo[: self._n]
        self._geo = geo
        self._store.resize(new_cap, self._n)

    def nbytes(self) -> int:
        """Bytes the map holds for its live points and shared feature tables (no spare capacity)."""
        return self._n * self._geo.itemsize * _GEO_COLS + self._store.nbytes(self._n)

    # ------------------------------------------------------------------ accessors
    @property
    def points(self) -> np.ndarray:
        """World positions, (N, 3) float32 (a copy)."""
        return self._geo[: self._n, _POS].copy()

    @property
    def normals(self) -> np.ndarray:
        """Unit normals, (N, 3) float32 (a copy)."""
        return self._geo[: self._n, _NRM].copy()

    @property
    def colors(self) -> np.ndarray:
        """Colours, (N, 3) uint8."""
        return np.clip(np.rint(self._geo[: self._n, _RGB]), 0, 255).astype(np.uint8)

    @property
    def confidence(self) -> np.ndarray:
        """Accumulated confidence ``c_k`` (eq. 2), (N,) float32 (a copy)."""
        return self._geo[: self._n, _CONF].copy()

    @property
    def feature_confidence(self) -> np.ndarray:
        """Confidence accumulated by each point's feature alone, (N,) float32."""
        return self._store.feature_weight(self._n)

    @property
    def has_feature(self) -> np.ndarray:
        """Whether each point has a concept vector, (N,) bool."""
        return self._store.has_feature(self._n)

    def features(self, indices=None) -> np.ndarray:
        """Unit-length concept vectors (zeros for points without one).

        Shape:
            ``indices`` (M,) int or None for all -> (M, d) float32.
        """
        idx = np.arange(self._n) if indices is None else np.asarray(indices, dtype=np.int64).reshape(-1)
        if idx.size and (idx.min() < 0 or idx.max() >= self._n):
            raise IndexError(f"indices: expected values in [0, {self._n - 1}], got [{idx.min()}, {idx.max()}]")
        return self._store.features(idx)

    def scores(self, query_d) -> np.ndarray:
        """Cosine similarity of every point's concept vector with a query vector.

        Points without a concept vector score NaN.

        Shape:
            ``query_d`` (d,) -> (N,) float32 in [-1, 1].
        """
        return self._store.scores(self.check_query(query_d), self._n)

    def check_query(self, query_d) -> np.ndarray:
        """``query_d`` as a float array once it is a finite, non-zero vector of the map's
        dimension (else ``ShapeError`` / ``ValueError`` saying what arrived).

        Shape:
            (d,) -> (d,).
        """
        q = as_float_array("query_d", np.asarray(query_d), shape=(self.feature_dim,))
        if not np.all(np.isfinite(q)) or not np.any(q):
            raise ValueError("query_d: expected a finite, non-zero vector")
        return q

    def scores_many(self, queries_qd) -> np.ndarray:
        """:meth:`scores` of several query vectors in one pass over the map (row ``q`` equals
        ``scores(queries_qd[q])`` exactly).

        Shape:
            ``queries_qd`` (Q, d) -> (Q, N) float32.
        """
        qs = as_float_array("queries_qd", np.asarray(queries_qd), shape=(None, self.feature_dim))
        if not np.all(np.isfinite(qs)) or not np.all(np.any(qs != 0, axis=1)):
            raise ValueError("queries_qd: expected finite, non-zero vectors")
        return self._store.scores_many(qs, self._n)

    # ------------------------------------------------------------------ fusion
    def integrate(self, rgb_hw3, depth_hw, K_33, cam_to_world_44, feats_hwd=None) -> IntegrationStats:
        """Fuse one posed RGB-D frame (and optionally its pixel-aligned features).

        Args:
            rgb_hw3: colour, uint8 or float in [0, 1].
            depth_hw: metric depth along the optical axis, float (metres).
            K_33: pinhole intrinsics.
            cam_to_world_44: OpenCV camera-to-world rigid pose.
            feats_hwd: the frame's features (zero vectors = no feature), one of: ``None``;
                a :class:`~conceptfusion.perception.features.PixelFeatures` (palette and
                per-pixel index); a pair ``(labels_hw, table_pd)``, the same as a label
                image (-1: no feature) and a table; or dense ``(H, W, d)`` features, grouped
                exactly into a palette (:func:`~conceptfusion.map.dense.palette_from_dense`,
                one pass over the array; the map is bit-identical to the one built from the
                same palette with rows in first-appearance order). Dense features with no
                repeats (per-pixel encoders) make the shared bank grow by every pixel's
                vector; pass them through
                :func:`~conceptfusion.map.quantize.quantize_features` for bounded memory.

        Shape:
            (H, W, 3), (H, W), (3, 3), (4, 4); features (H, W, d), PixelFeatures of (H, W)
            or ((H, W) int, (P, d) float).
        """
        depth = np.asarray(depth_hw) if isinstance(depth_hw, (list, tuple)) else depth_hw
        if isinstance(depth, np.ndarray) and depth.dtype.kind in "iu":
            raise DtypeError(
                f"depth_hw: expected float metres, got {depth.dtype} (convert millimetres with depth / 1000.0)"
            )
        depth = as_float_array("depth_hw", depth, shape=(None, None))
        h, w = depth.shape
        rgb = as_array("rgb_hw3", rgb_hw3, shape=(h, w, 3), kinds="uf")
        rgb = rgb.astype(np.float32) if rgb.dtype == np.uint8 else rgb.astype(np.float32) * 255.0
        K = check_intrinsics(K_33)
        T = check_pose(cam_to_world_44)
        pix_bank = self._frame_feature_ids(feats_hwd, h, w)

        pix, obs, alpha = _kernels.frame_points(
            np.ascontiguousarray(depth, np.float32),
            np.ascontiguousarray(rgb, np.float32),
            K,
            T,
            np.float32(min(self.config.max_depth, np.finfo(np.float32).max)),
            _confidence(h, w, tuple(K.ravel().tolist()), self.config.sigma).reshape(h, w),
        )
        bank = pix_bank[pix] if pix_bank is not None else np.full(len(pix), -1, np.int32)

        pts, sel, covered = self._associate(obs, pix, K, T, h, w)
        if len(pts):
            self._merge(pts, sel, obs, alpha, bank)
        fresh = ~covered
        fresh[sel] = False
        self._append(obs[fresh], alpha[fresh], bank[fresh])
        self._store.maybe_compact(self._n)
        self.frames_integrated += 1
        stats = IntegrationStats(int(len(pts)), int(covered.sum()), int(fresh.sum()), int(h * w - len(pix)), self._n)
        logger.debug("integrated frame %d: %s", self.frames_integrated, stats)
        return stats

    def _frame_feature_ids(self, feats, h: int, w: int) -> np.ndarray | None:
        """Bank id of each pixel's feature (-1: none), (H*W,) int32; None without features."""
        if feats is None:
            return None
        if isinstance(feats, np.ndarray):
            f = as_float_array("feats_hwd", feats, shape=(h, w, self.feature_dim))
            feats = palette_from_dense(f)
        elif isinstance(feats, tuple) and len(feats) == 2:
            labels, table = feats
            feats = PixelFeatures(
                as_float_array("feats_hwd table", table, shape=(None, self.feature_dim)),
                as_array("feats_hwd labels", labels, shape=(h, w), kinds="iu"),
            )
        elif not isinstance(feats, PixelFeatures):
            raise DtypeError(
                "feats_hwd: expected None, an (H, W, d) array, PixelFeatures or a (labels (H, W), table (P, d)) "
                f"pair, got {type(feats).__name__}"
            )
        if feats.shape != (h, w) or feats.dim != self.feature_dim:
            raise ShapeError(
                f"feats_hwd: expected features of shape ({h}, {w}, {self.feature_dim}), "
                f"got ({feats.shape[0]}, {feats.shape[1]}, {feats.dim})"
            )
        palette = feats.palette_pd
        if not np.all(np.isfinite(palette)):
            raise ValueError("feats_hwd: expected finite features, found NaN or inf")
        if len(palette) > _LARGE_PALETTE:
            logger.warning(
                "a frame with %d distinct features adds up to %.0f MB to the map's feature bank; "
                "quantise per-pixel features with conceptfusion.map.quantize.quantize_features",
                len(palette), palette.shape[0] * palette.shape[1] * 4 / 1e6,
            )
        nonzero = np.any(palette != 0, axis=1)
        ids = np.full(len(palette) + 1, -1, np.int32)  # last entry: index -1
        ids[: len(palette)][nonzero] = self._store.add_to_bank(palette[nonzero])
        return ids[feats.index_hw.ravel()]

    def _associate(self, obs, pix, K, T, h, w) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Projective data association (see ``_association``)."""
        if self._n == 0 or len(pix) == 0:
            return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(len(pix), bool)
        return associate(
            self._geo,
            self._n,
            np.linalg.inv(T),
            K,
            pix,
            obs,
            np.float32(self.config.dist_th**2),
            np.float32(math.cos(math.radians(self.config.angle_th_deg))),
            h,
            w,
        )

    def _merge(self, pts, sel, obs, alpha, bank) -> None:
        geo = self._geo
        run_ranges(  # each matched point is a distinct row: any split gives the same rows
            lambda a, b: _kernels.merge_geometry(geo, pts[a:b], sel[a:b], obs, alpha), len(pts), min_chunk=_MERGE_CHUNK
        )
        self._store.add_observations(pts, bank[sel], alpha[sel])

    def _append(self, obs, alpha, bank) -> None:
        m = len(obs)
        if m == 0:
            return
        self._reserve(m)
        rows = np.arange(self._n, self._n + m)
        block = self._geo[self._n : self._n + m]
        block[:, :9] = obs
        block[:, _CONF] = alpha
        self._store.clear_rows(self._n, self._n + m)
        self._store.add_observations(rows, bank, alpha)
        self._n += m

    # ------------------------------------------------------------------ state
    def state_dict(self) -> tuple[dict, dict[str, np.ndarray]]:
        """Everything needed to continue fusion exactly: (JSON-able header, arrays)."""
        header = {
            "feature_dim": self.feature_dim,
            "num_points": self._n,
            "frames_integrated": self.frames_integrated,
            "config": {
                "dist_th": self.config.dist_th,
                "angle_th_deg": self.config.angle_th_deg,
                "sigma": self.config.sigma,
                "max_depth": None if math.isinf(self.config.max_depth) else self.config.max_depth,
                "slots": self.config.slots,
            },
        }
        arrays = {"geometry": self._geo[: self._n]}
        arrays.update(self._store.state(self._n))
        return header, arrays

    def subset(self, indices) -> "PointFusionMap":
        """A new map holding only the given points, each exactly as it is here (geometry,
        colour, confidence, bank mixture), with the feature bank cut to the entries they use.

        Shape:
            ``indices`` (M,) int, distinct, in [0, N) -> a map of M points in that order.
        """
        idx = np.asarray(indices, dtype=np.int64).reshape(-1)
        if idx.size and (idx.min() < 0 or idx.max() >= self._n):
            raise IndexError(f"indices: expected values in [0, {self._n - 1}], got [{idx.min()}, {idx.max()}]")
        if len(np.unique(idx)) != len(idx):
            raise ValueError("indices: expected distinct point indices, got repeats")
        header, arrays = self.state_dict()
        ids = arrays["feat_point_ids"][idx]
        used = np.unique(ids[ids >= 0])
        remap = np.full(len(arrays["feat_bank"]) + 1, -1, np.int32)  # last entry: id -1 stays -1
        remap[used] = np.arange(len(used), dtype=np.int32)
        out = {
            "geometry": arrays["geometry"][idx],
            "feat_bank": arrays["feat_bank"][used],
            "feat_point_ids": remap[ids],
            "feat_point_w": arrays["feat_point_w"][idx],
            "feat_point_gram": arrays["feat_point_gram"][idx],
            "feat_point_sq": arrays["feat_point_sq"][idx],
        }
        return PointFusionMap.from_state_dict({**header, "num_points": len(idx)}, out)

    @classmethod
    def from_state_dict(cls, header: dict, arrays: dict[str, np.ndarray]) -> "PointFusionMap":
        """Inverse of :meth:`state_dict` (the caller validates shapes)."""
        cfg = dict(header["config"])
        if cfg.get("max_depth") is None:
            cfg["max_depth"] = math.inf
        m = cls(int(header["feature_dim"]), **cfg)
        n = int(header["num_points"])
        m._geo = np.array(arrays["geometry"], np.float32).reshape(n, _GEO_COLS)
        m._store = FeatureStore.from_state(m.feature_dim, m.config.slots, arrays)
        m._n = n
        m.frames_integrated = int(header["frames_integrated"])
        return m
