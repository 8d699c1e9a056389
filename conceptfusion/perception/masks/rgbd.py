"""The default mask proposer: multi-scale graph segmentation of RGB-D frames.

Needs no weights. Every 4-neighbour pixel pair gets an edge weight that adds three cues,
each capped at ``max_term``:

* **colour**: CIELAB distance of the (lightly blurred) image, over ``color_scale``;
* **depth**: how far the step in inverse depth between the two pixels departs from the
  steps just before and after it, relative to the inverse depth. Inverse depth is affine
  in the pixel coordinates on any plane, so a slanted floor costs nothing while an
  occluding edge costs a lot; over ``depth_tol``;
* **normal**: ``1 - cos`` of the angle between the two surface normals, over
  ``1 - cos(normal_tol_deg)``. Concave creases (normals converging: where a box stands on
  a table) pay in full; convex ones (normals diverging: two faces of one box) pay only
  ``convex_weight`` of it, the local convexity cue of RGB-D object segmentation.

A pixel pair with one invalid depth gets the full geometric cost; two invalid pixels
only the colour cost. Normals come from one-sided differences on the side of the smaller
depth change, so pixels next to an occluding edge keep their own surface's normal.

Segmentation has levels. Level 0 is graph-based segmentation (Felzenszwalb and
Huttenlocher, 2004) at scale ``fine_scale``: faces of objects, patches of texture. Each
further level merges adjacent regions of the previous one whose boundary edges have a mean
weight at most the next of ``merge_thresholds`` (a mean over a whole boundary does not
leak through the few weak edges that pixel-level merging does). The levels are nested: a
box face at level 0 lies inside its box at a coarser level, so proposals overlap as SAM's
do (part and object).

Regions are then filtered: too small, too large, mostly invalid depth, near-duplicates of
a region already proposed (IoU at least ``dedupe_iou``), and **background planes**. A
region is a background plane when its points fit a plane (``plane_inlier_fraction`` of
them within ``plane_tol_m``) and it covers at least ``background_min_fraction`` of the
frame or spans at least ``background_min_extent_m``: floors, walls, table tops. A plane's
crop is most of the frame, so its embedding adds little beyond the global one, while its
pixels under object masks would dilute them. Every pixel within ``plane_tol_m`` of a
background plane is background, and regions with at least ``background_overlap`` of
their pixels there are dropped too (floor patches cut off by the table, the table top
with an object merged in). With ``keep_background_planes=True`` each background plane is
instead proposed as exactly one mask (its pixels within tolerance), and the fragments
still go. Flat things lying within ``plane_tol_m`` of a background plane (a sheet of paper
on a table) are lost with it.

Output order: by area, largest first; ties by scale, then by first pixel in raster order.
The result is a pure function of the inputs (no randomness, no threading).
"""

from __future__ import annotations

import math
from dataclasses import fields

import cv2
import numpy as np

from conceptfusion.cameras import backproject
from conceptfusion.perception.masks.base import check_frame, empty_masks
from conceptfusion.perception.masks.regions import felzenszwalb, merge_levels, select_regions
from conceptfusion.perception.masks.rgbd_config import RGBDProposerConfig

__all__ = ["RGBDProposer"]

_REF_PIXELS = 240 * 320


class RGBDProposer:
    """Class-agnostic, overlapping masks from colour, depth and normal discontinuities.

    See the module docstring for the method. Deterministic; no weights.

    Args:
        config: settings (:class:`conceptfusion.perception.masks.rgbd_config.RGBDProposerConfig`);
            keyword overrides are applied on top.
    """

    privileged = False

    def __init__(self, config: RGBDProposerConfig | None = None, **overrides) -> None:
        base = config if config is not None else RGBDProposerConfig()
        if not isinstance(base, RGBDProposerConfig):
            raise TypeError(f"config: expected RGBDProposerConfig, got {type(base).__name__}")
        self.config = RGBDProposerConfig(**{**{f.name: getattr(base, f.name) for f in fields(base)}, **overrides})

    def propose(self, rgb_hw3, depth_hw, K_33) -> np.ndarray:
        """Masks of one frame (see :class:`conceptfusion.perception.masks.base.MaskProposer`).

        Shape:
            ``rgb_hw3`` (H, W, 3) uint8, ``depth_hw`` (H, W) float, ``K_33`` (3, 3)
            -> ``masks_rhw`` (R, H, W) bool, R <= ``max_masks``.
        """
        masks, _ = self.segment(rgb_hw3, depth_hw, K_33)
        return masks

    def segment(self, rgb_hw3, depth_hw, K_33) -> tuple[np.ndarray, np.ndarray]:
        """Masks and the segmentation level each came from (0: finest; see the module docstring).

        Shape:
            as :meth:`propose` -> ``masks_rhw`` (R, H, W) bool, ``level_r`` (R,) int64.
        """
        cfg = self.config
        rgb, depth, K = check_frame(rgb_hw3, depth_hw, K_33)
        h, w = depth.shape
        n = h * w
        with np.errstate(invalid="ignore"):
            depth = np.where(depth <= cfg.max_depth, depth, np.nan).astype(np.float32)
        if cfg.depth_median_px > 1:
            smooth = cv2.medianBlur(np.nan_to_num(depth, nan=0.0), cfg.depth_median_px)
            depth = np.where(np.isfinite(depth) & (smooth > 0), smooth, np.nan).astype(np.float32)
        valid = np.isfinite(depth)
        if not valid.any():
            return empty_masks(h, w), np.zeros(0, np.int64)
        vertex = backproject(depth, K)
        src, dst, weight = _edges(rgb, depth, vertex, _edge_aware_normals(vertex), valid, cfg)
        order = np.argsort(weight, kind="stable")
        k = cfg.fine_scale * (n / _REF_PIXELS)
        min_size = max(1, int(round(cfg.min_area_fraction * n)))
        fine, count = felzenszwalb(src[order], dst[order], weight[order], n, k, min_size)
        labels, counts = merge_levels(fine, count, src, dst, weight, cfg.merge_thresholds)
        return select_regions(labels, counts, vertex.reshape(n, 3), valid.reshape(n), cfg, h, w)


def _edges(rgb, depth, vertex, normals, valid, cfg: RGBDProposerConfig):
    """Right and down 4-neighbour edges with their combined weights.

    Shape:
        (H, W, 3), (H, W), vertex and normals (H, W, 3), (H, W) -> src (E,), dst (E,) int64,
        weight (E,) float32.
    """
    h, w = depth.shape
    img = rgb.astype(np.float32) / 255.0
    if cfg.blur_sigma > 0:
        img = cv2.GaussianBlur(img, (0, 0), cfg.blur_sigma)
    lab = cv2.cvtColor(img, cv2.COLOR_RGB2Lab)
    lab_weight = np.array([cfg.lightness_weight, 1.0, 1.0], np.float32)
    inv = np.where(valid, 1.0 / np.where(valid, depth, 1.0), np.nan).astype(np.float32)
    cos_tol = math.cos(math.radians(cfg.normal_tol_deg))
    idx = np.arange(h * w, dtype=np.int64).reshape(h, w)
    srcs, dsts, weights = [], [], []
    for axis in (1, 0):  # right neighbours, then down neighbours
        a = [slice(None), slice(None)]
        b = [slice(None), slice(None)]
        a[axis], b[axis] = slice(None, -1), slice(1, None)
        a, b = tuple(a), tuple(b)
        color = np.linalg.norm((lab[a] - lab[b]) * lab_weight, axis=-1) / cfg.color_scale
        depth_cost = _inverse_depth_jump(inv, axis) / cfg.depth_tol
        with np.errstate(invalid="ignore"):
            dot = np.sum(normals[a] * normals[b], axis=-1)
            convex = np.sum((normals[a] - normals[b]) * (vertex[a] - vertex[b]), axis=-1) > 0
        normal_cost = np.nan_to_num((1.0 - dot) / (1.0 - cos_tol), nan=0.0)
        normal_cost = np.where(convex, cfg.convex_weight * normal_cost, normal_cost)
        geo = np.minimum(np.nan_to_num(depth_cost, nan=0.0), cfg.max_term) + np.minimum(normal_cost, cfg.max_term)
        both = valid[a] & valid[b]
        one = valid[a] ^ valid[b]
        geo = np.where(both, geo, np.where(one, 2.0 * cfg.max_term, 0.0))
        weights.append((np.minimum(color, cfg.max_term) + geo).astype(np.float32).ravel())
        srcs.append(idx[a].ravel())
        dsts.append(idx[b].ravel())
    return np.concatenate(srcs), np.concatenate(dsts), np.concatenate(weights)


def _edge_aware_normals(vertex_hw3: np.ndarray) -> np.ndarray:
    """Unit normals from one-sided differences, each axis taking the side with the smaller
    depth change, so pixels next to an occluding edge keep their own surface's normal.

    Orientation is irrelevant here (only ``n_p . n_q`` and convexity use them, both
    invariant to flipping both normals; a consistent sign is kept by facing the camera).
    NaN where no valid neighbour exists on either side along an axis.

    Shape:
        (H, W, 3) -> (H, W, 3) float32.
    """
    v = vertex_hw3.astype(np.float32)
    tangents = []
    for axis in (1, 0):
        d = np.diff(v, axis=axis)
        pad = np.full_like(np.take(d, [0], axis=axis), np.nan)
        fwd = np.concatenate([d, pad], axis=axis)
        bwd = np.concatenate([pad, d], axis=axis)
        with np.errstate(invalid="ignore"):
            use_bwd = np.isnan(fwd[..., 2]) | (np.abs(bwd[..., 2]) < np.abs(fwd[..., 2]))
        tangents.append(np.where(use_bwd[..., None], bwd, fwd))
    n = np.cross(tangents[0], tangents[1])
    with np.errstate(invalid="ignore", divide="ignore"):
        n = n / np.linalg.norm(n, axis=-1, keepdims=True)
        flip = np.sum(n * v, axis=-1, keepdims=True) > 0
    return np.where(flip, -n, n).astype(np.float32)


def _inverse_depth_jump(inv_hw: np.ndarray, axis: int) -> np.ndarray:
    """Relative departure of each neighbour step of inverse depth from the adjacent steps.

    For pixels ``p``, ``q`` along ``axis`` with steps ``s_prev`` (into ``p``), ``s`` (p to
    q) and ``s_next`` (out of ``q``): ``min(|s - s_prev|, |s - s_next|) / mean(inv_p,
    inv_q)``, using whichever adjacent steps exist (``|s|`` when neither does). Zero on
    any plane, large at occluding edges. NaN where ``p`` or ``q`` is invalid.

    Shape:
        (H, W) -> (H, W-1) for axis 1, (H-1, W) for axis 0.
    """
    x = inv_hw if axis == 1 else inv_hw.T
    s = np.diff(x, axis=1)  # (H, W-1)
    pad = np.full((x.shape[0], 1), np.nan, x.dtype)
    prev = np.concatenate([pad, s[:, :-1]], axis=1)
    nxt = np.concatenate([s[:, 1:], pad], axis=1)
    with np.errstate(invalid="ignore"):
        dev = np.fmin(np.abs(s - prev), np.abs(s - nxt))
        dev = np.where(np.isnan(prev) & np.isnan(nxt), np.abs(s), dev)
        rel = dev / (0.5 * (x[:, :-1] + x[:, 1:]))
    return rel if axis == 1 else rel.T
