"""Querying a fused map: scores, the paper's relative threshold, a calibrated "is it here?"
decision, and 3D regions.

* :func:`relative_scores` is the paper's post-processing: cosine ``s`` mapped to
  ``(s + 1) / 2`` and min-max normalised over the map, thresholded (0.6 for text queries in
  the reference code). It is *relative*: the best-matching points always pass, so an object
  that is not in the map is still "found".
* :func:`relevancy` is a calibrated alternative (LERF): for each point, the smallest over
  generic negative phrases ("object", "things", "stuff", "texture") of
  ``softmax(T * [s_query, s_negative])[0]``. Above 0.5 the point is closer to the query than
  to every generic phrase; an absent object leaves no such region, so the answer can be
  "not in this map".
* :func:`locate` combines both and clusters the selected points into :class:`Region` s.
* :func:`vocabulary_margins` answers a different question, "which of these objects is it?",
  for a caller that knows the object is among given candidates (the things on a table): each
  candidate's points score the query against every name the encoder was trained to tell apart,
  so an object the encoder sees as something else it knows loses to one it cannot name.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from conceptfusion._checks import as_float_array
from conceptfusion.errors import ShapeError
from conceptfusion.map.regions import Region, SupportTest, support_mask

__all__ = [
    "NEGATIVE_PHRASES",
    "QueryResult",
    "relative_scores",
    "relevancy",
    "connected_regions",
    "locate",
    "regions_batch",
    "vocabulary_margins",
    "click_query_vector",
]

NEGATIVE_PHRASES: tuple[str, ...] = ("object", "things", "stuff", "texture")
"""Generic phrases a query must beat to count as present (as in LERF)."""


@dataclass(frozen=True)
class QueryResult:
    """The answer to one query over a map.

    Shape:
        ``scores_n``, ``relative_n``, ``relevancy_n``: (N,) float32 over all map points, NaN
        where a point has no concept vector.
    """

    found: bool
    """Whether any region passed the calibrated decision."""
    regions: list[Region]
    """Connected regions, best first (empty when not found)."""
    scores_n: np.ndarray
    """Raw cosine similarity of each point with the query."""
    relative_n: np.ndarray
    """The paper's min-max normalised score in [0, 1]."""
    relevancy_n: np.ndarray
    """Calibrated relevancy in [0, 1] (0.5: as close to the query as to a generic phrase)."""
    reason: str = ""
    """Why nothing was found, when nothing was."""
    extras: dict = field(default_factory=dict)

    @property
    def best(self) -> Region | None:
        """The best region, or ``None`` when not found."""
        return self.regions[0] if self.regions else None


def relative_scores(scores_n: np.ndarray) -> np.ndarray:
    """The paper's score: ``(s + 1) / 2`` min-max normalised over the points (NaN kept).

    Shape:
        (N,) -> (N,) float32 in [0, 1]; all equal scores give 1.
    """
    s = (np.asarray(scores_n, np.float32) + 1.0) / 2.0
    finite = np.isfinite(s)
    if not finite.any():
        return s
    lo, hi = float(s[finite].min()), float(s[finite].max())
    if hi - lo < 1e-12:
        return np.where(finite, 1.0, np.nan).astype(np.float32)
    return ((s - lo) / (hi - lo)).astype(np.float32)


def relevancy(scores_n: np.ndarray, negative_scores_kn: np.ndarray, *, temperature: float = 10.0) -> np.ndarray:
    """Calibrated relevancy: ``min_k softmax(T * [s, s_neg_k])[0]`` per point.

    Shape:
        ``scores_n`` (N,), ``negative_scores_kn`` (K, N) -> (N,) float32 in [0, 1].
    """
    s = np.asarray(scores_n, np.float32)
    neg = np.asarray(negative_scores_kn, np.float32)
    if neg.ndim != 2 or neg.shape[1] != s.shape[0] or neg.shape[0] == 0:
        raise ShapeError(f"negative_scores_kn: expected shape (K >= 1, {s.shape[0]}), got {neg.shape}")
    margin = temperature * (neg.max(axis=0) - s)  # the hardest negative decides
    with np.errstate(over="ignore"):
        return (1.0 / (1.0 + np.exp(margin))).astype(np.float32)


def connected_regions(
    points_n3: np.ndarray,
    selected_n: np.ndarray,
    scores_n: np.ndarray,
    *,
    voxel_size: float = 0.03,
    min_points: int = 20,
) -> list[Region]:
    """Group selected points into spatially connected regions, best mean score first.

    Points are binned into voxels of ``voxel_size`` metres; voxels sharing a face, edge or
    corner are connected. Regions with fewer than ``min_points`` points are dropped.

    Shape:
        ``points_n3`` (N, 3), ``selected_n`` (N,) bool, ``scores_n`` (N,) -> list of Region.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    pts = as_float_array("points_n3", np.asarray(points_n3), shape=(None, 3))
    sel = np.asarray(selected_n, bool)
    if sel.shape != (len(pts),):
        raise ShapeError(f"selected_n: expected shape ({len(pts)},), got {sel.shape}")
    if voxel_size <= 0:
        raise ValueError(f"voxel_size: expected a positive size, got {voxel_size}")
    idx = np.flatnonzero(sel)
    if idx.size == 0:
        return []
    cells = np.floor(pts[idx] / voxel_size).astype(np.int64)
    cells -= cells.min(axis=0)
    span = cells.max(axis=0) + 3
    key = ((cells[:, 0] + 1) * span[1] + (cells[:, 1] + 1)) * span[2] + (cells[:, 2] + 1)
    uniq, point_voxel = np.unique(key, return_inverse=True)
    rows, cols = [], []
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            for dz in (-1, 0, 1):
                if (dx, dy, dz) <= (0, 0, 0):
                    continue  # each neighbour pair once
                nb = uniq + (dx * span[1] + dy) * span[2] + dz
                pos = np.searchsorted(uniq, nb)
                pos = np.minimum(pos, len(uniq) - 1)
                hit = uniq[pos] == nb
                rows.append(np.flatnonzero(hit))
                cols.append(pos[hit])
    r = np.concatenate(rows)
    c = np.concatenate(cols)
    graph = coo_matrix((np.ones(len(r), np.int8), (r, c)), shape=(len(uniq), len(uniq)))
    _, voxel_label = connected_components(graph, directed=False)
    label = voxel_label[point_voxel.ravel()]
    regions = []
    scores = np.asarray(scores_n, np.float32)
    order = np.argsort(label, kind="stable")
    counts = np.bincount(label)
    starts = np.concatenate([[0], np.cumsum(counts)])
    for lab in np.flatnonzero(counts >= min_points):
        members = idx[order[starts[lab] : starts[lab + 1]]]
        regions.append(Region(points_n3=pts[members].astype(np.float64), scores_n=scores[members], indices_n=members))
    regions.sort(key=lambda reg: (-reg.score, -reg.num_points))
    return regions


def locate(
    map_,
    query_d: np.ndarray,
    negatives_kd: np.ndarray,
    *,
    relative_threshold: float = 0.6,
    relevancy_threshold: float = 0.6,
    temperature: float = 10.0,
    voxel_size: float = 0.03,
    min_points: int = 20,
    support: SupportTest | None = SupportTest(),
) -> QueryResult:
    """Find where a query vector is in a map, or say it is not there.

    A point is selected when its relative score (paper) is at least ``relative_threshold``
    **and** its relevancy against the negative phrases is at least ``relevancy_threshold``.
    Selected points are clustered into regions (:func:`connected_regions`). With ``support``
    (and a map with normals), each region loses the horizontal surface it stands on when it
    has bled into one (:func:`~conceptfusion.map.regions.drop_support`: the table rim around a
    mug's base); regions left with fewer than ``min_points`` points are dropped and the rest
    re-ranked. The query is found when at least one region has ``min_points`` points.

    Args:
        map_: a :class:`~conceptfusion.map.fusion.PointFusionMap`.
        query_d: the query vector (text, image, click or audio embedding).
        negatives_kd: embeddings of generic phrases (see :data:`NEGATIVE_PHRASES`).

    Shape:
        ``query_d`` (d,), ``negatives_kd`` (K, d).
    """
    neg = as_float_array("negatives_kd", np.asarray(negatives_kd), shape=(None, map_.feature_dim))
    if hasattr(map_, "scores_many"):  # the query and its negatives in one pass over the map
        q = map_.check_query(query_d)
        both = map_.scores_many(np.concatenate([q[None], neg.astype(np.float32)]))
        scores, neg_scores = both[0], both[1:]
    else:
        scores = map_.scores(query_d)
        neg_scores = np.stack([map_.scores(n) for n in neg]) if len(neg) else np.zeros((0, len(scores)), np.float32)
    normals = getattr(map_, "normals", None) if support is not None else None
    return _answer(len(map_), map_.points, normals, scores, neg_scores, relative_threshold=relative_threshold,
                   relevancy_threshold=relevancy_threshold, temperature=temperature, voxel_size=voxel_size,
                   min_points=min_points, support=support)


def regions_batch(
    map_,
    queries_qd: np.ndarray,
    negatives_kd: np.ndarray,
    *,
    chunk: int = 16,
    relative_threshold: float = 0.6,
    relevancy_threshold: float = 0.6,
    temperature: float = 10.0,
    voxel_size: float = 0.03,
    min_points: int = 20,
    support: SupportTest | None = SupportTest(),
) -> list[list[Region]]:
    """The regions :func:`locate` would find for each query (empty: not found), without the
    per-point arrays: what listing the objects a map holds needs. A query that no point scores
    above its hardest negative for (relevancy below ``relevancy_threshold`` everywhere) is
    answered empty without clustering; the hardest negative is taken once for all queries.

    Shape:
        ``queries_qd`` (Q, d), ``negatives_kd`` (K >= 1, d) -> Q lists of regions, best first.
    """
    qs = as_float_array("queries_qd", np.asarray(queries_qd), shape=(None, map_.feature_dim)).astype(np.float32)
    neg = as_float_array("negatives_kd", np.asarray(negatives_kd), shape=(None, map_.feature_dim)).astype(np.float32)
    if len(neg) == 0:
        raise ShapeError("negatives_kd: expected at least one negative phrase's embedding, got 0")
    if isinstance(chunk, bool) or not isinstance(chunk, int) or chunk < 1:
        raise ValueError(f"chunk: expected an integer >= 1, got {chunk!r}")
    neg_max = map_.scores_many(neg).max(axis=0)
    # relevancy >= threshold  <=>  T * (neg_max - s) <= log(1 / threshold - 1): a bound on s per point
    bound = neg_max + np.float32(-np.log(1.0 / relevancy_threshold - 1.0) / temperature) if 0 < relevancy_threshold < 1 else None
    points = normals = None
    out: list[list[Region]] = []
    for start in range(0, len(qs), chunk):
        for scores in map_.scores_many(qs[start:start + chunk]):
            with np.errstate(invalid="ignore"):
                if bound is not None and not np.any(scores >= bound - 1e-6):
                    out.append([])
                    continue
            if points is None:
                points = map_.points
                normals = map_.normals if support is not None else None
            res = _answer(len(map_), points, normals, scores, neg_max[None], relative_threshold=relative_threshold,
                          relevancy_threshold=relevancy_threshold, temperature=temperature, voxel_size=voxel_size,
                          min_points=min_points, support=support)
            out.append(res.regions)
    return out


def _answer(n: int, points, normals, scores, neg_scores, *, relative_threshold, relevancy_threshold, temperature, voxel_size,
            min_points, support) -> QueryResult:
    """:func:`locate`'s answer from a query's scores over the map's points and its negatives'."""
    rel = relative_scores(scores)
    relev = relevancy(scores, neg_scores, temperature=temperature) if len(neg_scores) else np.ones_like(scores)
    with np.errstate(invalid="ignore"):
        selected = (rel >= relative_threshold) & (relev >= relevancy_threshold)
    regions = connected_regions(points, selected, scores, voxel_size=voxel_size, min_points=min_points)
    dropped = 0
    if regions and normals is not None:
        regions, dropped = _without_support(points, np.asarray(normals), regions, support, min_points)
    reason = ""
    if n == 0 or not np.isfinite(scores).any():
        reason = "the map has no points with concept vectors"
    elif not regions:
        best = float(np.nanmax(relev))
        reason = (
            f"no region of at least {min_points} points beats the generic phrases "
            f"(best relevancy {best:.2f} < {relevancy_threshold})"
            if best < relevancy_threshold
            else f"selected points form no region of at least {min_points} points"
            + (f" ({dropped} lay on the surface under them)" if dropped else "")
        )
    return QueryResult(bool(regions), regions, scores, rel, relev, reason)


def vocabulary_margins(map_, query_d: np.ndarray, vocabulary_kd: np.ndarray, candidates: Sequence[Region]) -> np.ndarray:
    """How much each candidate region looks like the query rather than like any name of a
    vocabulary: the median over the region's points (those with a concept vector) of
    ``cos(f, query) - max_k cos(f, vocabulary_k)``.

    An object whose concept vectors resemble a known name more than the query (a mug, for "the
    stapler") scores below 0; the object the query names scores near 0 when the query is a
    vocabulary name and highest among the candidates when the encoder never learned its look
    (it resembles no known name well). Zero-shot classification over the candidates, with the
    query added to the classes.

    Args:
        map_: a :class:`~conceptfusion.map.fusion.PointFusionMap`.
        query_d: the query's embedding.
        vocabulary_kd: embeddings of the vocabulary's names (at least one).
        candidates: regions of ``map_`` with their point indices (``indices_n``).

    Shape:
        ``query_d`` (d,), ``vocabulary_kd`` (K, d) -> (R,) float64; ``-inf`` for a candidate
        with no point that has a concept vector.

    Raises:
        ShapeError: wrong shapes, or an empty vocabulary.
        ValueError: a candidate without point indices, or indices outside the map.
    """
    q = map_.check_query(query_d).astype(np.float32)
    voc = as_float_array("vocabulary_kd", np.asarray(vocabulary_kd), shape=(None, map_.feature_dim)).astype(np.float32)
    if len(voc) == 0:
        raise ShapeError("vocabulary_kd: expected at least one name's embedding, got 0")
    q = q / max(float(np.linalg.norm(q)), 1e-12)
    voc = voc / np.maximum(np.linalg.norm(voc, axis=1, keepdims=True), 1e-12)
    has = map_.has_feature
    out = np.full(len(candidates), -np.inf)
    for i, reg in enumerate(candidates):
        idx = np.asarray(reg.indices_n, np.int64).reshape(-1)
        if idx.size == 0:
            raise ValueError(f"candidates[{i}]: expected a region of the map with point indices (indices_n), got none")
        if idx.min() < 0 or idx.max() >= len(has):
            raise ValueError(f"candidates[{i}]: point indices outside the map's {len(has)} points")
        idx = idx[has[idx]]
        if idx.size:
            f = map_.features(idx)
            out[i] = float(np.median(f @ q - (f @ voc.T).max(axis=1)))
    return out


def _without_support(points_n3, normals_n3, regions: list[Region], test: SupportTest, min_points: int) -> tuple[list[Region], int]:
    """``regions`` each without the surface it stands on (:func:`~conceptfusion.map.regions.drop_support`), those left
    with at least ``min_points`` points, re-ranked as :func:`connected_regions` ranks; and how
    many regions were dropped."""
    up = normals_n3[:, 2] >= test.up_cos
    up_idx = np.flatnonzero(up)  # once for every region
    out = []
    for reg in regions:
        keep, z0 = support_mask(points_n3, up, up_idx, reg.indices_n.astype(np.int64), test)
        if keep is None:
            out.append(reg)
        elif keep.sum() >= min_points:
            out.append(Region(points_n3=reg.points_n3[keep], scores_n=reg.scores_n[keep], indices_n=reg.indices_n[keep]))
    out.sort(key=lambda reg: (-reg.score, -reg.num_points))
    return out, len(regions) - len(out)


def click_query_vector(map_, point_world_3: Sequence[float], *, max_distance: float = 0.05) -> np.ndarray:
    """The fused concept vector at a clicked 3D point (the paper's click query).

    Takes the nearest map point that has a concept vector; raises ``ValueError`` when none
    lies within ``max_distance`` metres of the click.

    Shape:
        ``point_world_3`` (3,) -> (d,) float32 unit vector.
    """
    p = as_float_array("point_world_3", np.asarray(point_world_3, dtype=np.float64), shape=(3,))
    has = np.flatnonzero(map_.has_feature)
    if has.size == 0:
        raise ValueError("click query: the map has no points with concept vectors")
    d2 = np.sum((map_.points[has] - p) ** 2, axis=1)
    k = int(np.argmin(d2))
    if d2[k] > max_distance**2:
        raise ValueError(
            f"click query: expected a click on the map's surface, nearest point is "
            f"{np.sqrt(d2[k]):.3f} m away (max_distance={max_distance} m)"
        )
    return map_.features([has[k]])[0]
